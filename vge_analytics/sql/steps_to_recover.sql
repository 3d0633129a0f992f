-- metric: StepsToRecover
-- title: Steps To Recover after the cut
-- direction: lower
-- unit: ratio
-- level: episode-mean
-- grain: episodes
-- version: 1
-- definition: Mean, over a continuation run's episodes that were continued after the cut,
--   whose source episode failed and which succeeded, of the agent's scored steps after the
--   cut: the scored steps less the source's steps replayed (prefix_steps) and the fix (one
--   step when fixed). The episodes RecoveryRate counts as recovered.
-- null: null when the group has no recovered episode.

-- numerator
sum(L_act - prefix_steps - CAST(fixed AS BIGINT)) FILTER (WHERE continued AND NOT source_success AND success)

-- denominator
count(*) FILTER (WHERE continued AND NOT source_success AND success)
