"""The error taxonomy and the switch classes (PROTOCOL §5), per group, in DuckDB.

The queries live in `sql/error_distribution.sql` and `sql/switch_classes.sql`; they read a
relation `scoped` (one row per scored step of the selection, with the group key `__g`, a
struct of the grouping columns) that this module builds with the same column checks and
bound filters as the metrics.
"""

from __future__ import annotations

from collections.abc import Sequence

import polars as pl

import replay
from replay.io import STEPS_TABLE

from ..store import (
    COUNTS_TABLE,
    Filters,
    GroupBy,
    Store,
    check_columns,
    counted_steps,
    grouped_aggregate,
    open_store,
    parse_by,
    quote_ident,
    run_query,
)
from ._queries import query_text

ERROR_TYPES: tuple[str, ...] = tuple(replay.ERROR_TYPES)
"""The paper's seven error types, in the order of its tables."""
ERROR_GROUPS: dict[str, str] = dict(replay.ERROR_GROUPS)
"""error type -> grounding / execution / navigation."""
GROUP_ORDER: tuple[str, ...] = ("grounding", "execution", "navigation")
SWITCH_CLASSES: tuple[str, ...] = tuple(replay.SWITCH_CLASSES)

ERROR_LABELS: dict[str, str] = {
    "invalid_coord": "Invalid Coord Error",
    "component_selection": "Component Selection Error",
    "params_error": "Params Error",
    "action_error": "Action Error",
    "invalid_waiting": "Invalid Waiting",
    "switch_view_nn": "Switch View NN",
    "switch_view_pn": "Switch View PN",
}
"""The paper's names of the error types (for tables meant for people)."""


def _scoped(
    store: Store, grain: str, by: Sequence[str], where: Filters, column: str, count: str
) -> tuple[str, list]:
    """Scored steps counted per group and `column`, with the group key as a struct `__g`."""
    counted, params = grouped_aggregate(
        store, grain, by, where, [(count, "n")], extra_keys=[(f"g.{column}", column)]
    )
    if by:
        key = "struct_pack(" + ", ".join(f"{quote_ident(c)} := c.{quote_ident(c)}" for c in by)
        key += ")"
    else:
        key = "struct_pack(__all := 1)"
    return f"SELECT {key} AS __g, c.{column}, c.n FROM ({counted}) AS c", params


def _run(
    store: Store,
    name: str,
    by: Sequence[str],
    where: Filters,
    params: list,
    column: str,
    count: tuple[str, str],
    part: str,
) -> pl.DataFrame:
    """Query `name` over the scored steps counted per group and `column`: added up from the
    steps counted per run kept beside OUT (`store.counted_steps`; `count[1]`, the kept count
    to add, of `part`) where they answer, else counted on the steps table (`count[0]`)."""
    check_columns(store, [*by, *(where or {})], [STEPS_TABLE], "grouping/filter")
    counted = counted_steps(store, part, [*by, *(where or {})])
    if counted is None:
        scoped, scope_params = _scoped(store, STEPS_TABLE, by, where, column, count[0])
    else:  # integers: the same sums in any order; typed as the count of the steps table
        kept = f"CAST(sum(g.{quote_ident(count[1])}) AS BIGINT)"
        scoped, scope_params = _scoped(counted, COUNTS_TABLE, by, where, column, kept)
        store = counted
    sql = f"WITH scoped AS ({scoped}) SELECT * FROM ({query_text(name)}) AS q"
    df = run_query(store, sql, [*scope_params, *params])
    df = df.unnest("__g")
    if not by:
        df = df.drop("__all")
    return df


def error_distribution(
    out, by: GroupBy = None, where: Filters = None, *, labels: bool = False
) -> pl.DataFrame:
    """Error-type distribution per group: the paper's pie, with counts.

    Columns: the group columns, `error_group`, `error_type`, `count` (scored steps with that
    error type) and `share` (percent of the group's errors; null when it has none). All seven
    types appear for every group, in the paper's order. `labels=True` adds `label` (the
    paper's name of the type).
    """
    store = open_store(out)
    by_cols = list(parse_by(by))
    types = list(ERROR_TYPES)
    groups = [ERROR_GROUPS[t] for t in types]
    df = _run(
        store,
        "error_distribution",
        by_cols,
        where,
        [types, groups, types],
        "error_type",
        ("count(*)", "scored"),
        "errors",
    )
    df = df.sort([*by_cols, "type_order"], nulls_last=True).drop("type_order")
    df = df.with_columns(pl.col("count").cast(pl.Int64), pl.col("share").cast(pl.Float64))
    if labels:
        df = df.with_columns(label=pl.col("error_type").replace_strict(ERROR_LABELS))
    return df


def error_groups(out, by: GroupBy = None, where: Filters = None) -> pl.DataFrame:
    """Error-group distribution per group (grounding / execution / navigation).

    Columns: the group columns, `error_group`, `count`, `share` (percent of the group's
    errors; null when it has none).
    """
    by_cols = list(parse_by(by))
    return groups_of(error_distribution(out, by_cols, where), by_cols)


def groups_of(types: pl.DataFrame, by: Sequence[str]) -> pl.DataFrame:
    """The error-group distribution from an `error_distribution` result (no new query)."""
    by_cols = list(by)
    order = {g: i for i, g in enumerate(GROUP_ORDER)}
    keys = [*by_cols, "error_group"]
    total = pl.col("count").sum().over(by_cols) if by_cols else pl.col("count").sum()
    df = (
        types.group_by(keys, maintain_order=True)
        .agg(pl.col("count").sum())
        .with_columns(
            share=pl.when(total > 0).then(100.0 * pl.col("count") / total).otherwise(None),
            __order=pl.col("error_group").replace_strict(order),
        )
        .sort([*by_cols, "__order"], nulls_last=True)
        .drop("__order")
    )
    return df.with_columns(pl.col("count").cast(pl.Int64), pl.col("share").cast(pl.Float64))


def switch_classes(out, by: GroupBy = None, where: Filters = None) -> pl.DataFrame:
    """Switch-class distribution (NP, PN, NN, PP) of successful view switches per group.

    Columns: the group columns, `switch_class`, `count`, `share` (percent of the group's
    classified switches; null when none), `switches` (all successful switches of the group,
    including those without a class).
    """
    store = open_store(out)
    by_cols = list(parse_by(by))
    classes = list(SWITCH_CLASSES)
    df = _run(
        store,
        "switch_classes",
        by_cols,
        where,
        [classes, classes],
        "switch_class",
        ("count(*) FILTER (WHERE g.is_switch)", "switches"),
        "switches",
    )
    df = df.sort([*by_cols, "class_order"], nulls_last=True).drop("class_order")
    return df.with_columns(
        pl.col("count").cast(pl.Int64),
        pl.col("share").cast(pl.Float64),
        pl.col("switches").cast(pl.Int64),
    )


__all__ = [
    "ERROR_GROUPS",
    "ERROR_LABELS",
    "ERROR_TYPES",
    "GROUP_ORDER",
    "SWITCH_CLASSES",
    "error_distribution",
    "error_groups",
    "groups_of",
    "switch_classes",
]
