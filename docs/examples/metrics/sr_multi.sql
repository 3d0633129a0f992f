-- metric: SR-multi
-- title: Success Rate on multi-goal episodes
-- direction: higher
-- unit: percent
-- level: episode-mean
-- grain: episodes
-- version: 1
-- definition: Mean, over the episodes with more than one goal, of success, in percent (the
--   SR a reviewer asks for on multi-goal tasks only).
-- null: null when the group has no episode with more than one goal.

-- numerator
count(*) FILTER (WHERE success AND n_goals > 1)

-- denominator
count(*) FILTER (WHERE n_goals > 1)
