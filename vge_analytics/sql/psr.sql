-- metric: PSR
-- title: Perfect Sub-task success Rate
-- direction: higher
-- unit: percent
-- level: goal-ratio
-- grain: goals
-- version: 1
-- definition: Goals completed in at most C_opt_dyn steps (the optimal cost from the situation
--   in which the goal became current) over all goals of the group's episodes, in percent.
--   Computed from completed, steps_used and c_opt_dyn (not from the stored perfect column).
-- null: null when the group has no goal.

-- numerator
count(*) FILTER (WHERE completed AND c_opt_dyn IS NOT NULL AND steps_used <= c_opt_dyn)

-- denominator
count(*)
