"""Row-level access for the dashboard: runs with facets, episodes, goals and steps.

Every function takes an OUT directory (or an open `Store`), validates column names against
the tables, binds every value, and returns a polars DataFrame with a stable column order
(the tables' own) and a deterministic row order.
"""

from __future__ import annotations

from collections.abc import Sequence

import polars as pl

import replay
from replay.io import EPISODES_TABLE, GOALS_TABLE, RUNS_TABLE, STEPS_TABLE

from .._errors import UnknownColumnError, UnknownRunError
from ._scope import Filters, build_scope, check_columns, quote_ident
from ._sql import run_query
from ._store import open_store


def runs(out) -> pl.DataFrame:
    """One row per run: the runs table (run_id, model, agent_kind, lambda, meta facets...)
    plus `n_episodes`, `n_success` and `n_steps` (scored steps), sorted by run_id."""
    store = open_store(out)
    sql = (
        "WITH e AS (SELECT run_id, count(*) AS n_episodes, "
        'count(*) FILTER (WHERE success) AS n_success, sum("L_act") AS n_steps '
        "FROM episodes GROUP BY run_id) "
        "SELECT r.*, coalesce(e.n_episodes, 0) AS n_episodes, "
        "coalesce(e.n_success, 0) AS n_success, coalesce(e.n_steps, 0) AS n_steps "
        "FROM runs AS r LEFT JOIN e ON e.run_id = r.run_id ORDER BY r.run_id"
    )
    return run_query(store, sql, [])


def run_columns(out, columns: Sequence[str]) -> pl.DataFrame:
    """`columns` of the runs table alone, a row per run sorted by run_id: without `runs`'
    counts, which read the episodes table (1.6 s at 100x the full benchmark)."""
    return _select(out, RUNS_TABLE, None, columns, ["run_id"])


def facets(out) -> dict[str, list]:
    """Run facets (`meta_<key>` columns of runs) and their distinct values, sorted."""
    store = open_store(out)
    result: dict[str, list] = {}
    for col in store.meta_columns:
        if not store.is_scalar(RUNS_TABLE, col):
            continue
        q = quote_ident(col)
        rows = run_query(store, f"SELECT DISTINCT {q} AS v FROM runs ORDER BY v NULLS LAST", [])
        result[col] = rows["v"].to_list()
    return result


def _select(
    out, grain: str, where: Filters, columns: Sequence[str] | None, order: Sequence[str]
) -> pl.DataFrame:
    store = open_store(out)
    check_columns(store, list(where or {}), [grain], "filter")
    scope = build_scope(store, grain, [], where, scored_only=False)
    if columns:
        unknown = [c for c in columns if not store.has_column(grain, c)]
        if unknown:
            raise UnknownColumnError(
                f"unknown {grain} column(s) {', '.join(map(repr, unknown))}; "
                f"columns: {', '.join(store.columns[grain])}"
            )
        select = ", ".join(f"g.{quote_ident(c)}" for c in columns)
    else:
        select = "g.*"
    order_sql = ", ".join(f"g.{quote_ident(c)}" for c in order)
    sql = f"SELECT {select} FROM {scope.from_sql} WHERE {scope.where_sql} ORDER BY {order_sql}"
    return run_query(store, sql, scope.params)


def episodes(out, where: Filters = None, columns: Sequence[str] | None = None) -> pl.DataFrame:
    """Episode rows (PROTOCOL §7 columns), filtered by any column of episodes or runs (e.g.
    `{"run_id": [...], "category": "Microwave", "meta_history": 3}`), sorted by run_id,
    episode_id. `columns` limits the columns returned."""
    return _select(out, EPISODES_TABLE, where, columns, ["run_id", "episode_id"])


def goals(out, where: Filters = None, columns: Sequence[str] | None = None) -> pl.DataFrame:
    """Goal rows, filtered like `episodes`, sorted by run_id, episode_id, goal_index."""
    return _select(out, GOALS_TABLE, where, columns, ["run_id", "episode_id", "goal_index"])


def steps(out, where: Filters = None, columns: Sequence[str] | None = None) -> pl.DataFrame:
    """Step rows (truncated ones included, see the `truncated` column), filtered by any column
    of steps, episodes or runs, sorted by run_id, episode_id, step."""
    return _select(out, STEPS_TABLE, where, columns, ["run_id", "episode_id", "step"])


def episode_steps(out, run_id: str, episode_id: str) -> pl.DataFrame:
    """Every step of one episode (truncated ones included), in log order."""
    store = open_store(out)
    if run_id not in store.run_ids():
        raise UnknownRunError(f"unknown run {run_id!r} in {store.out}")
    return steps(store, where={"run_id": run_id, "episode_id": episode_id})


def steps_with_error(
    out,
    error_type: str | Sequence[str],
    where: Filters = None,
    columns: Sequence[str] | None = None,
    limit: int | None = None,
) -> pl.DataFrame:
    """Scored steps whose error type is `error_type` (one or several; an error group name
    such as `grounding` selects its types), optionally filtered further, sorted by run_id,
    episode_id, step; `limit` keeps the first rows."""
    wanted = [error_type] if isinstance(error_type, str) else list(error_type)
    types: list[str] = []
    for item in wanted:
        if item in replay.ERROR_GROUPS:
            types.append(item)
        elif item in replay.ERROR_GROUPS.values():
            types.extend(t for t, g in replay.ERROR_GROUPS.items() if g == item)
        else:
            raise UnknownColumnError(
                f"unknown error type {item!r}; types: {', '.join(replay.ERROR_GROUPS)}; "
                "groups: grounding, execution, navigation"
            )
    filters = dict(where or {})
    filters["error_type"] = types
    filters["truncated"] = False
    df = steps(out, where=filters, columns=columns)
    return df.head(limit) if limit is not None else df


__all__ = [
    "episode_steps",
    "episodes",
    "facets",
    "goals",
    "run_columns",
    "runs",
    "steps",
    "steps_with_error",
]
