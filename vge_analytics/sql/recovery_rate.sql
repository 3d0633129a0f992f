-- metric: RecoveryRate
-- title: Recovery Rate of continued episodes
-- direction: higher
-- unit: percent
-- level: episode-mean
-- grain: episodes
-- version: 1
-- definition: Of a continuation run's episodes that were continued after the cut (the
--   source's steps replayed, the fix when asked, then the agent; PROTOCOL §10.4) and whose
--   source episode failed, the share that succeeded, in percent. Copied episodes (nothing to
--   cut at) and episodes whose source succeeded do not count; ordinary runs have none.
-- null: null when the group has no continued episode whose source failed.

-- numerator
count(*) FILTER (WHERE continued AND NOT source_success AND success)

-- denominator
count(*) FILTER (WHERE continued AND NOT source_success)
