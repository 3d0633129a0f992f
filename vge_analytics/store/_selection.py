"""Selections that match nothing: a filter value, a run id or an episode id that OUT does
not hold is named in one line with the nearest values it does hold (difflib), so a typo
gets an answer instead of an empty table (docs/ANALYSIS.md, "Filters that match nothing").

`check_selection(out, where)` tells, for `where` filters (`--where`, the dashboard's
facets and pickers), which values no row holds and whether the filters together select
no row; `check_runs` refuses run ids that are not in OUT, naming the nearest.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from replay.io import EPISODES_TABLE, GRAINS

from .._errors import UnknownRunError
from .._nearest import nearest_hint
from ._scope import (
    Filters,
    _normalise_filter,
    build_scope,
    check_columns,
    quote_ident,
    source_table,
)
from ._sql import run_query
from ._store import Store, open_store

SHOWN = 5
"""Values that match nothing named, per column (the others are counted)."""
MAX_CANDIDATES = 2_000
"""Distinct values of a column read to look for the nearest (a column of steps may hold
many): the first ones in sort order, enough for a typo of a run, model or category."""


@dataclass(frozen=True)
class SelectionCheck:
    """What filters select: the values no row holds, and whether together they select no
    row at all."""

    misses: tuple[str, ...]
    """One phrase per value no row holds: `no model 'sim-vlm-z' (nearest: sim-vlm-a, ...)`."""
    empty: bool
    """The filters select no row (of episodes, or of the table their columns need)."""

    def line(self, shown: str) -> str | None:
        """One line about the filters `shown` (as the user gave them), or None when every
        value matches: they select no row (and why), or which values match nothing."""
        if self.empty:
            why = "; ".join(self.misses) or "each value is there, but no row has them all"
            return f"{shown} selects no row: {why}"
        if self.misses:
            return f"{shown}: {'; '.join(self.misses)} (the other values select rows)"
        return None


def check_runs(store: Store, run_ids: Sequence[str]) -> list[str]:
    """OUT's run ids; raises `UnknownRunError` for the first of `run_ids` that is not one,
    naming the nearest (`unknown run 'sim-vlm-q' in OUT; nearest: sim-vlm-a, ...`)."""
    known = store.run_ids()
    for run in run_ids:
        if run not in known:
            raise UnknownRunError(
                f"unknown run {run!r} in {store.out}{nearest_hint(run, known, 'run')}"
            )
    return known


def describe_filters(where: Filters) -> str:
    """Filters as a person reads them: `model = sim-vlm-a, category = Kettle or Lamp`."""
    parts = []
    for column, value in (where or {}).items():
        values, allow_null = _normalise_filter(value)
        shown = [str(v) for v in values] + (["(none)"] if allow_null else [])
        parts.append(f"{column} = {' or '.join(shown)}")
    return ", ".join(parts)


def _grain(store: Store, columns: Sequence[str]) -> str | None:
    """The table whose rows the filters select: episodes (with the columns of runs), else
    steps or goals when a column is theirs only; None when no table has them all."""
    for grain in GRAINS:
        if all(source_table(store, grain, c) is not None for c in columns):
            return grain
    return None


def _present(store: Store, table: str, column: str, values: Sequence[object]) -> set[str]:
    """Which of `values` (as text) some row of `table` holds in `column`: one scan, however
    many values (a value that is not of the column's type is held by none)."""
    sql_type = store.columns[table][column]
    sql = (
        "SELECT DISTINCT w FROM (SELECT unnest(CAST(? AS VARCHAR[])) AS w) "
        f"WHERE TRY_CAST(w AS {sql_type}) IN (SELECT {quote_ident(column)} FROM {table})"
    )
    return set(run_query(store, sql, [[str(v) for v in values]])["w"].to_list())


def _has_null(store: Store, table: str, column: str) -> bool:
    sql = f"SELECT 1 FROM {table} WHERE {quote_ident(column)} IS NULL LIMIT 1"
    return run_query(store, sql, []).height > 0


def _values(store: Store, table: str, column: str) -> list[str]:
    """The first `MAX_CANDIDATES` distinct values of a column, as text, sorted."""
    col = quote_ident(column)
    sql = (
        f"SELECT DISTINCT CAST({col} AS VARCHAR) AS v FROM {table} WHERE {col} IS NOT NULL "
        f"ORDER BY v LIMIT {MAX_CANDIDATES}"
    )
    return run_query(store, sql, [])["v"].to_list()


def check_selection(out, where: Filters) -> SelectionCheck:
    """Which values of `where` ({column: value or values}, as the analytics take them) no
    row of OUT holds, with the nearest each column does hold, and whether the filters select
    no row together. Unknown columns raise `UnknownColumnError` as in every query."""
    filters: Mapping[str, object] = dict(where or {})
    if not filters:
        return SelectionCheck((), False)
    store = open_store(out)
    grain = _grain(store, list(filters))
    check_columns(store, list(filters), [grain or EPISODES_TABLE], "filter")
    misses: list[str] = []
    matched: dict[str, list[object]] = {}
    for column, value in filters.items():
        table = source_table(store, grain, column)
        values, allow_null = _normalise_filter(value)
        present = _present(store, table, column, values) if values else set()
        found: list[object] = [v for v in values if str(v) in present]
        if allow_null and _has_null(store, table, column):
            found.append(None)
        missing = [v for v in values if str(v) not in present]
        missing += [None] if allow_null and None not in found else []
        if missing:
            known = _values(store, table, column)
        for v in missing[:SHOWN]:
            hint = nearest_hint(v, known, "value")
            misses.append(f"no {column} {'(none)' if v is None else repr(v)} ({hint[2:]})")
        if len(missing) > SHOWN:
            misses.append(f"and {len(missing) - SHOWN:,} more {column} values that no row holds")
        matched[column] = found
    if any(not found for found in matched.values()):
        return SelectionCheck(tuple(misses), True)
    scope = build_scope(store, grain, [], matched, scored_only=False)
    sql = f"SELECT 1 FROM {scope.from_sql} WHERE {scope.where_sql} LIMIT 1"
    return SelectionCheck(tuple(misses), run_query(store, sql, scope.params).height == 0)


__all__ = ["SelectionCheck", "check_runs", "check_selection", "describe_filters"]
