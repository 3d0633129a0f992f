-- query: switch_classes
-- version: 1
-- definition: Switch-class distribution per group (the paper's switch-view figure): for each
--   class NP, PN, NN, PP, the number of successful Switch_view steps (scored) of that class
--   and its share of the group's classified switches, in percent; `switches` is every
--   successful switch of the group, including those with no class (the current goal had no
--   target components). Shares are null when the group has no classified switch.
-- input: `scoped`, the scored steps of the selection counted per group and switch_class:
--   the group key `__g`, `switch_class` (null: no class) and `n` (successful switches).
-- parameters: 1. the switch classes in display order, 2. the same (for their positions).

WITH counts AS (
    SELECT __g, switch_class, sum(n) AS n
    FROM scoped
    WHERE switch_class IS NOT NULL
    GROUP BY ALL
),
grid AS (
    SELECT __g, sum(n) AS switches, sum(n) FILTER (WHERE switch_class IS NOT NULL) AS classified
    FROM scoped
    GROUP BY ALL
),
classes AS (
    SELECT
        unnest(CAST(? AS VARCHAR[])) AS switch_class,
        generate_subscripts(CAST(? AS VARCHAR[]), 1) AS class_order
)
SELECT
    grid.__g,
    classes.class_order,
    classes.switch_class,
    coalesce(counts.n, 0) AS "count",
    100.0 * coalesce(counts.n, 0) / nullif(grid.classified, 0) AS share,
    grid.switches
FROM grid
CROSS JOIN classes
LEFT JOIN counts
    ON counts.__g IS NOT DISTINCT FROM grid.__g AND counts.switch_class = classes.switch_class
