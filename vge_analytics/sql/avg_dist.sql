-- metric: AvgDist
-- title: Average Distance to the nearest target
-- direction: lower
-- unit: distance
-- level: step-ratio
-- grain: steps
-- version: 1
-- definition: Mean, over the group's scored interactions that have a distance (a target
--   component has a bbox in the current view), of the Euclidean distance on the 0..1000 scale
--   from the point to the nearest such bbox (0 inside).
-- null: null when no step of the group has a distance.

-- numerator
fsum(distance)

-- denominator
count(distance)
