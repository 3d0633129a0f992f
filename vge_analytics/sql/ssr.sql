-- metric: SSR
-- title: Sub-task Success Rate
-- direction: higher
-- unit: percent
-- level: episode-mean
-- grain: episodes
-- version: 1
-- definition: Mean over episodes of goals_completed / n_goals, in percent (each episode weighs
--   the same, whatever its number of goals).
-- null: null when the group has no episode.

-- numerator
fsum(CAST(goals_completed AS DOUBLE) / n_goals)

-- denominator
count(*)
