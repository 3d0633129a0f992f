-- query: diff
-- version: 1
-- definition: Two runs' trajectories compared episode by episode (`vge diff`), one row per
--   episode both runs replayed: its device, their scored steps (`L_act`) and success; each run's first
--   step with an error type and that type (null: no error); the first step at which the two
--   replays' `state_after` or `view_after` differ, where a step that only one run has
--   counts as a difference (so when one run is a prefix of the other it is the shorter
--   length), null when both are identical. Only scored steps are compared: truncated steps
--   were not replayed (PROTOCOL §3.5) and have no state.
-- input: the tables `episodes` and `steps`.
-- parameters: $1 run A, $2 run B, $3 the episode ids to keep (a list), or null for every
--   common episode.

WITH pair AS (
    SELECT
        a.episode_id,
        a.device_id,
        a."L_act" AS steps_a,
        b."L_act" AS steps_b,
        a.success AS success_a,
        b.success AS success_b
    FROM (SELECT episode_id, device_id, "L_act", success FROM episodes WHERE run_id = $1) AS a
    JOIN (SELECT episode_id, "L_act", success FROM episodes WHERE run_id = $2) AS b
        ON a.episode_id = b.episode_id
    WHERE CAST($3 AS VARCHAR[]) IS NULL
        OR a.episode_id IN (SELECT unnest(CAST($3 AS VARCHAR[])))
),
log_a AS (
    SELECT episode_id, step, state_after, view_after, error_type
    FROM steps
    WHERE run_id = $1 AND NOT truncated AND episode_id IN (SELECT episode_id FROM pair)
),
log_b AS (
    SELECT episode_id, step, state_after, view_after, error_type
    FROM steps
    WHERE run_id = $2 AND NOT truncated AND episode_id IN (SELECT episode_id FROM pair)
),
errors_a AS (
    SELECT episode_id, min(step) AS first_error, arg_min(error_type, step) AS error_type
    FROM log_a
    WHERE error_type IS NOT NULL
    GROUP BY episode_id
),
errors_b AS (
    SELECT episode_id, min(step) AS first_error, arg_min(error_type, step) AS error_type
    FROM log_b
    WHERE error_type IS NOT NULL
    GROUP BY episode_id
),
-- A full join pairs step k of A with step k of B; a step missing on one side (the other
-- run went on) is a difference too, at the shorter run's length.
difference AS (
    SELECT coalesce(a.episode_id, b.episode_id) AS episode_id,
        min(coalesce(a.step, b.step)) AS first_difference
    FROM log_a AS a
    FULL JOIN log_b AS b ON a.episode_id = b.episode_id AND a.step = b.step
    WHERE a.step IS NULL
        OR b.step IS NULL
        OR a.state_after IS DISTINCT FROM b.state_after
        OR a.view_after IS DISTINCT FROM b.view_after
    GROUP BY 1
)
SELECT
    pair.episode_id,
    pair.steps_a,
    pair.steps_b,
    pair.success_a,
    pair.success_b,
    errors_a.first_error AS first_error_a,
    errors_b.first_error AS first_error_b,
    difference.first_difference,
    errors_a.error_type AS first_error_type_a,
    errors_b.error_type AS first_error_type_b,
    pair.device_id
FROM pair
LEFT JOIN errors_a ON errors_a.episode_id = pair.episode_id
LEFT JOIN errors_b ON errors_b.episode_id = pair.episode_id
LEFT JOIN difference ON difference.episode_id = pair.episode_id
ORDER BY pair.episode_id
