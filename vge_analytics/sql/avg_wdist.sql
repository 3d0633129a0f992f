-- metric: AvgWDist
-- title: Average Weighted Distance
-- direction: lower
-- unit: distance
-- level: step-ratio
-- grain: steps
-- version: 1
-- definition: sum(weight * distance) / count over the same steps as AvgDist; the weight is
--   1 + the earlier non-progress interactions of the same goal whose nearest target was the
--   same component, so repeated misses of one target weigh more.
-- null: null when no step of the group has a distance.

-- numerator
fsum(weight * distance) FILTER (WHERE distance IS NOT NULL)

-- denominator
count(distance)
