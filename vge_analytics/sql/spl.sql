-- metric: SPL
-- title: Success weighted by Path Length
-- direction: higher
-- unit: percent
-- level: episode-mean
-- grain: episodes
-- version: 1
-- definition: Mean over episodes of S * L_opt / max(L_act, L_opt), in percent; S is success
--   (0/1), L_opt = sum of the goals' static C_opt, L_act = scored (non-truncated) steps.
--   When L_opt = 0 the episode's SPL is S. Computed from success, L_opt and L_act (not from
--   the stored spl column), so a change here needs no replay.
-- null: null when the group has no episode.

-- numerator
fsum(
    CASE
        WHEN NOT success THEN 0.0
        WHEN "L_opt" = 0 THEN 1.0
        ELSE CAST("L_opt" AS DOUBLE) / greatest("L_act", "L_opt")
    END
)

-- denominator
count(*)
