-- metric: PSR
-- title: Perfect Sub-task success Rate (over the goals reached)
-- direction: higher
-- unit: percent
-- level: goal-ratio
-- grain: goals
-- version: 2
-- definition: Goals completed in at most C_opt_dyn steps over the goals that became current
--   (reached), in percent: a goal the agent never got to no longer counts against it. Overrides
--   the built-in PSR, whose denominator is every goal of the group's episodes.
-- null: null when the group reached no goal.

-- numerator
count(*) FILTER (WHERE completed AND c_opt_dyn IS NOT NULL AND steps_used <= c_opt_dyn)

-- denominator
count(*) FILTER (WHERE reached)
