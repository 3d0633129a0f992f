-- metric: SR
-- title: Success Rate
-- direction: higher
-- unit: percent
-- level: episode-mean
-- grain: episodes
-- version: 1
-- definition: Mean over episodes of success, in percent. An episode succeeds when all of its
--   goals were completed (termination = success) before a budget ran out.
-- null: null when the group has no episode.

-- numerator
count(*) FILTER (WHERE success)

-- denominator
count(*)
