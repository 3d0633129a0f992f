-- metric: GVPE
-- title: Global View switches Per Episode (per completed goal)
-- direction: lower
-- unit: ratio
-- level: run-level ratio
-- grain: episodes
-- version: 1
-- definition: All successful view switches of the group's scored steps (failed episodes
--   included) divided by all goals completed in the group; a pooled ratio, not a mean of
--   per-episode ratios.
-- null: null when the group completed no goal.

-- numerator
sum(n_switches)

-- denominator
sum(goals_completed)
