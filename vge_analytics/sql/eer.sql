-- metric: EER
-- title: Effective Exploration Rate
-- direction: higher
-- unit: percent
-- level: step-ratio
-- grain: steps
-- version: 1
-- definition: EER-valid steps over non-switch steps, in percent; pooled over every scored step
--   of the group. Non-switch steps are all steps except Switch_view attempts (successful or
--   not); parse failures count as operations. A step is EER-valid when it triggered a
--   transition or unlocked the dashboard and is neither dangerous nor repetitive. The replay
--   leaves eer_valid null exactly on Switch_view attempts (and truncated steps), so the
--   denominator counts the non-null eer_valid values (the polars check counts the steps
--   whose action_type is not switch_view instead: the two must agree).
-- null: null when the group has no non-switch step.

-- numerator
count(*) FILTER (WHERE eer_valid)

-- denominator
count(eer_valid)
