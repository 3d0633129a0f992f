-- metric: VSPS
-- title: View Switches Per Success
-- direction: lower
-- unit: ratio
-- level: episode-mean
-- grain: episodes
-- version: 1
-- definition: Mean, over the episodes that completed at least one goal, of
--   (successful view switches taken while a goal that was later completed was current)
--   / goals completed. Episodes without a completed goal do not count.
-- null: null when no episode of the group completed a goal.

-- numerator
fsum(CAST(vsps_switches AS DOUBLE) / goals_completed) FILTER (WHERE goals_completed > 0)

-- denominator
count(*) FILTER (WHERE goals_completed > 0)
