"""The Grounding page: clicks on a device view, and what they hit."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import polars as pl

from replay.io import STEPS_TABLE

from ..store import (
    COUNTS_TABLE,
    Filters,
    build_scope,
    check_columns,
    counted_steps,
    grouped_aggregate,
    open_store,
    run_query,
)
from ._first_rows import runs_holding_first
from ._pictures import device_machine, view_boxes


def interaction_views(out: str | Path, where: Filters = None) -> pl.DataFrame:
    """(device_id, category, view, interactions) for every device view clicked in, most
    clicked first: what the grounding scatter can show. Added up from the steps counted per
    run kept beside OUT (`store.counted_steps`) where they answer, else counted on the steps."""
    store = open_store(out)
    check_columns(store, list(where or {}), [STEPS_TABLE], "filter")
    order = " ORDER BY interactions DESC, device_id, view"
    counted = counted_steps(store, "views", list(where or {}))
    if counted is not None:  # integers: the same sums in any order, typed as a count
        keys = ["device_id", "category", "view_before"]
        total = [("CAST(sum(g.interactions) AS BIGINT)", "interactions")]
        summed, params = grouped_aggregate(counted, COUNTS_TABLE, keys, where, total)
        sql = (
            "SELECT device_id, category, view_before AS view, "
            f"CAST(interactions AS BIGINT) AS interactions FROM ({summed}) AS c "
            f"WHERE interactions > 0{order}"
        )
        return run_query(counted, sql, params)
    scope = build_scope(store, STEPS_TABLE, [], where)
    sql = (
        "SELECT g.device_id, g.category, g.view_before AS view, count(*) AS interactions "
        f"FROM {scope.from_sql} WHERE {scope.where_sql} AND g.is_interaction "
        f"GROUP BY ALL{order.replace('device_id', 'g.device_id')}"
    )
    return run_query(store, sql, scope.params)


def device_labels(views: pl.DataFrame) -> dict[str, str]:
    """{device_id: `<device> (<category>): <n> clicks`} of an `interaction_views` result, most
    clicked first."""
    per = views.group_by("device_id", "category", maintain_order=True).agg(
        pl.col("interactions").sum()
    )
    return {
        d: f"{d} ({c}): {n} clicks"
        for d, c, n in per.sort("interactions", descending=True, maintain_order=True).iter_rows()
    }


CLICK_OUTCOMES: tuple[str, ...] = ("target hit", "other component", "miss")
"""How a click point is coloured in the grounding scatter."""


def click_points(
    out: str | Path, device_id: str, view: str, where: Filters = None, *, limit: int = 5000
) -> pl.DataFrame:
    """Interactions on one device view: run_id, model, episode_id, step, x, y, outcome
    (`target hit`, `other component`, `miss`), error_type, distance, nearest_target."""
    store = open_store(out)
    check_columns(store, list(where or {}), [STEPS_TABLE], "filter")
    clicks = (
        "AND g.is_interaction AND g.device_id = ? AND g.view_before = ? "
        "AND g.x IS NOT NULL AND g.y IS NOT NULL"
    )
    scope = build_scope(store, STEPS_TABLE, [], where)
    base = f"FROM {scope.from_sql} WHERE {scope.where_sql} {clicks}"
    runs, _ = runs_holding_first(store, base, [*scope.params, device_id, view], int(limit))
    # The columns are read from the runs of the first clicks only (same rows).
    scope = build_scope(store, STEPS_TABLE, [], {**(where or {}), "run_id": runs})
    sql = (
        "SELECT g.run_id, g.model, g.episode_id, g.step, g.x, g.y, "
        "CASE WHEN g.hit_target THEN 'target hit' WHEN g.hit_component THEN 'other component' "
        "ELSE 'miss' END AS outcome, g.error_type, g.distance, g.nearest_target "
        f"FROM {scope.from_sql} WHERE {scope.where_sql} {clicks} "
        "ORDER BY g.run_id, g.episode_id, g.step LIMIT ?"
    )
    params = [*scope.params, device_id, view, int(limit)]
    return run_query(store, sql, params)


def clicked_targets(points: pl.DataFrame) -> tuple[str, ...]:
    """The components that were the nearest target of some click of a `click_points` result."""
    return tuple(sorted(t for t in points["nearest_target"].unique().to_list() if t is not None))


def scatter_boxes(
    out: str | Path,
    device_id: str,
    view: str,
    targets: Sequence[str],
    run_id: str | None = None,
) -> pl.DataFrame:
    """The component boxes of a device view for the scatter: component, x0, y0, x1, y1 and
    role, `target` for the components named in `targets` (see `clicked_targets`)."""
    machine = device_machine(out, device_id, run_id)
    boxes = view_boxes(machine, view, targets=list(targets))
    return pl.DataFrame(
        [
            {
                "component": b.component,
                "x0": b.x0,
                "y0": b.y0,
                "x1": b.x1,
                "y1": b.y1,
                "role": b.role,
            }
            for b in boxes
        ],
        schema={
            "component": pl.String,
            "x0": pl.Float64,
            "y0": pl.Float64,
            "x1": pl.Float64,
            "y1": pl.Float64,
            "role": pl.String,
        },
    )


def click_counts(points: pl.DataFrame) -> dict[str, int]:
    """{outcome: clicks} of a `click_points` result, every outcome present."""
    counts = dict.fromkeys(CLICK_OUTCOMES, 0)
    for outcome, n in points.group_by("outcome").len().iter_rows():
        counts[outcome] = int(n)
    return counts
