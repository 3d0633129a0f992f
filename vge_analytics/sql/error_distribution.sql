-- query: error_distribution
-- version: 1
-- definition: Error-type distribution per group (the paper's error pie): for each of the
--   seven PROTOCOL §5 error types, the number of scored steps with that error_type and its share of
--   all the group's errors, in percent. Every type appears for every group (count 0 when
--   absent); the shares of a group add up to 100, or are null when the group has no error.
-- input: `scoped`, the scored steps of the selection counted per group and error_type: the
--   group key `__g` (a struct of the grouping columns), `error_type` (null: no error) and
--   `n` (steps).
-- parameters: 1. error types in taxonomy order, 2. their error groups (same order),
--   3. the error types again (for their positions).

WITH counts AS (
    SELECT __g, error_type, sum(n) AS n
    FROM scoped
    WHERE error_type IS NOT NULL
    GROUP BY ALL
),
grid AS (
    SELECT DISTINCT __g FROM scoped
),
taxonomy AS (
    SELECT
        unnest(CAST(? AS VARCHAR[])) AS error_type,
        unnest(CAST(? AS VARCHAR[])) AS error_group,
        generate_subscripts(CAST(? AS VARCHAR[]), 1) AS type_order
)
SELECT
    grid.__g,
    taxonomy.type_order,
    taxonomy.error_group,
    taxonomy.error_type,
    coalesce(counts.n, 0) AS "count",
    100.0 * coalesce(counts.n, 0)
        / nullif(sum(coalesce(counts.n, 0)) OVER (PARTITION BY grid.__g), 0) AS share
FROM grid
CROSS JOIN taxonomy
LEFT JOIN counts
    ON counts.__g IS NOT DISTINCT FROM grid.__g AND counts.error_type = taxonomy.error_type
