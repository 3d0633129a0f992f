"""A metric's terms per (run, episode), kept beside OUT with the episodes' cluster columns.

An interval of the Leaderboard resamples each group's clusters of episodes: it needs every
episode's numerator and denominator of the metric, and the episode's device and category.
At 100 times the full benchmark (9.3 million episodes) computing them took most of a first
visit: the terms' query over the grain table, the episodes' columns, and a join of the two.
The first computation keeps them, a file per metric, in
`OUT/.metric-cache/terms_<grain>-<contents>-<definition>.parquet`
(`replay.io.episode_terms_path`): run_id, episode_id, the episodes' columns of
`EPISODE_COLUMNS`, and the metric's terms, the rows the direct computation joins (the terms
of the metric's own query grouped by run_id and episode_id, unfiltered, joined to the
episodes; for a metric of the episodes whose terms are counts or sums, the same rows read
as a projection of the episodes table, `_episode_rows`). Later computations read the file
and keep the rows `where` selects. (A file per metric, not per grain: the terms of every
metric of the episodes per episode in one query needed more than a command's memory limit
at 100x.)

Filtering the kept rows gives the same rows and the same bits as filtering before: a filter
on a column fixed per episode (its device, category, goal count) or per run (run_id, model,
a facet) selects whole episodes, and an episode's terms add up the same rows either way. A
filter or grouping on any other column (a step's or a goal's) is answered from the tables.

Keyed as the per-run terms are (`_cache`): OUT's contents and the metric's definition; another
replay, a table file changed by hand or another metric file names another file. Bounded: at
most `MAX_TERMS_FILES` files (the oldest go, and those of other contents), none read over
`MAX_TERMS_BYTES`; a file that is a link, not a regular file, not Parquet or without the
columns and types written here is computed again.
"""

from __future__ import annotations

import contextlib
import dataclasses
from collections.abc import Callable, Sequence
from pathlib import Path

import duckdb
import polars as pl

from replay.io import EPISODES_TABLE, RUNS_TABLE, episode_terms_path

from .._errors import QueryError
from ._bounds import query_bounds
from ._cache import _where, definitions_key
from ._episode_rows import projected_terms
from ._kept import keep_parts, read_kept_frame, unless_failed
from ._ratios import Ratio, ratio_terms, term_name
from ._scope import (
    Filters,
    _filter_condition,
    check_columns,
    grouped_aggregate,
    quote_ident,
    run_level,
)
from ._sql import run_query
from ._store import Store

EPISODE_COLUMNS: tuple[str, ...] = ("device_id", "category", "n_goals")
"""The episodes' columns kept beside the terms: the clusters an interval resamples (device,
category; `episode_id` is a key) and the Leaderboard's episode filters and groupings."""

MAX_TERMS_BYTES = 1 << 30
"""A kept file of terms over this is not read (a row per episode: 9.3 million rows at 100x
the full benchmark, every metric of the steps, in well under this)."""

EPISODES_PER_QUERY = 500_000
"""Episodes whose terms one query computes when they are kept (`_run_parts`): at 100 times the
full benchmark, the whole in one query (an aggregate, a sort and a join of 9.3 million rows)
took 3.1 GB of memory at its peak, in parts of this size 1.1 GB, in about the same time."""

MAX_TERMS_FILES = 32
"""Files of terms kept for one content of OUT (one per metric: 14 built-in)."""

_KEYS = ("run_id", "episode_id")


def _held(store: Store) -> list[str]:
    """The columns of `EPISODE_COLUMNS` the episodes table has as scalars."""
    return [c for c in EPISODE_COLUMNS if store.is_scalar(EPISODES_TABLE, c)]


def _answers(store: Store, columns: Sequence[str], held: Sequence[str]) -> bool:
    """Whether kept rows can be selected and grouped on `columns`: each held, run_id or
    fixed per run."""
    return all(c in _KEYS or c in held or run_level(store, EPISODES_TABLE, c) for c in columns)


def _compute(
    store: Store,
    ratio: Ratio,
    held: Sequence[str],
    sources,
    runs: Sequence[str] | None = None,
) -> pl.DataFrame:
    """The rows of `_grouped`: as a projection of the episodes table when the terms are
    counts or sums over it (`_episode_rows`, the same rows without grouping or join), else
    grouped."""
    projected = projected_terms(store, ratio, held, sources, runs)
    if projected is not None:
        return projected
    return _grouped(store, ratio, held, sources, runs)


def _grouped(
    store: Store,
    ratio: Ratio,
    held: Sequence[str],
    sources,
    runs: Sequence[str] | None = None,
) -> pl.DataFrame:
    """The rows the direct computation joins: the terms of `ratio` per (run, episode) (its
    grain's rows grouped by run_id and episode_id, as `episode_terms` groups them; an
    episode without rows has none) joined to the episodes' keys and `held` columns, in one
    statement (the join in DuckDB, within the query's memory bound), sorted by run and
    episode (an interval sorts its rows so: sorted already, 9.3 million took 1.3 to 1.9 s,
    not 2.9); `runs`: those of these runs alone (a filter on run_id, which skips the other
    runs' files), the same rows."""
    where = None if runs is None else {"run_id": list(runs)}
    check_columns(store, [*_KEYS, *(where or {})], [ratio.grain], "grouping/filter")
    sql, params = grouped_aggregate(store, ratio.grain, _KEYS, where, ratio_terms([ratio]))
    names = [term_name(ratio, p) for p in ("num", "den")]
    select = ", ".join(
        [*(f"t.{quote_ident(c)}" for c in _KEYS), *(f"e.{quote_ident(c)}" for c in held)]
        + [f"coalesce(t.{quote_ident(n)}, 0) AS {quote_ident(n)}" for n in names]
    )
    columns = "".join(f", {quote_ident(c)}" for c in held)
    on_runs = "TRUE"
    if runs is not None:
        on_runs = _filter_condition("run_id", store.columns[EPISODES_TABLE]["run_id"], runs, params)
    joined = (
        f"SELECT {select} FROM ({sql}) AS t JOIN (SELECT run_id AS __run_id, episode_id AS "
        f"__episode_id{columns} FROM episodes WHERE {on_runs}) AS e "
        "ON e.__run_id = t.run_id AND e.__episode_id = t.episode_id ORDER BY t.run_id, t.episode_id"
    )
    return run_query(store, joined, params, sources=sources)


def _run_parts(store: Store) -> list[list[str]]:
    """OUT's runs (the manifest's, sorted: the parts' rows follow each other in order) in
    parts of about `EPISODES_PER_QUERY` episodes (the manifest's count over its runs), at
    least one part."""
    listed = store.manifest.get("runs", [])
    runs = sorted({r["run_id"] for r in listed if isinstance(r.get("run_id"), str)})
    totals = store.manifest.get("totals")
    episodes = totals.get("replayed") if isinstance(totals, dict) else None
    if not isinstance(episodes, int) or episodes <= 0 or not runs:
        return [runs]
    per = max(1, EPISODES_PER_QUERY * len(runs) // episodes)
    return [runs[i : i + per] for i in range(0, len(runs), per)]


def _valid(frame: pl.DataFrame, held: Sequence[str], names: Sequence[str]) -> bool:
    """Whether a kept frame holds the keys as text, `held` as text or integers, and every
    term in `names` as numbers (a sum of integers is a decimal in DuckDB)."""
    schema = frame.schema

    def typed(name: str, check: Callable[[pl.DataType], bool]) -> bool:
        return name in schema and check(schema[name])

    def text(kind: pl.DataType) -> bool:
        return kind == pl.String

    return (
        all(typed(n, text) for n in _KEYS)
        and all(typed(n, lambda t: text(t) or t.is_integer()) for n in held)
        and all(typed(n, lambda t: t.is_numeric()) for n in names)
    )


def _read(
    path: Path, held: Sequence[str], names: Sequence[str], rows: int | None = None
) -> pl.DataFrame | None:
    """The keys, `held` and `names` of the kept frame at `path` (its first `rows`: 0 for
    its columns alone), or None when it is absent or not one this module writes."""
    frame = read_kept_frame(path, MAX_TERMS_BYTES, [*_KEYS, *held, *names], rows)
    return frame if frame is not None and _valid(frame, held, names) else None


def _keep(store: Store, ratio: Ratio, held: Sequence[str], sources) -> Path | None:
    """The file of the terms of `ratio` per (run, episode) in OUT's cache folder, computed
    and written first when no valid one is there (its columns and types read, not its rows);
    None when OUT keeps nothing or cannot be written. Written a part of the runs at a time
    (`_run_parts`), so that neither DuckDB's join nor the result holds all the episodes."""
    out = _where(store)
    if out is None:
        return None
    names = [term_name(ratio, p) for p in ("num", "den")]
    path = episode_terms_path(out, ratio.grain, store.contents, definitions_key([ratio]))
    if _read(path, held, names, rows=0) is not None:
        return path
    parts = (_compute(store, ratio, held, sources, runs) for runs in _run_parts(store))
    return path if keep_parts(path, parts, "terms_*.parquet", MAX_TERMS_FILES) else None


def _kept_table(store: Store, ratio: Ratio, held: Sequence[str], sources) -> pl.DataFrame | None:
    """The terms of `ratio` per (run, episode) from OUT's cache folder, computed and kept
    first when missing (`_keep`), then read; computed here, a part at a time, when OUT
    cannot be written or the file written cannot be read (over `MAX_TERMS_BYTES`); None
    when OUT keeps nothing."""
    if _where(store) is None:
        return None
    path = _keep(store, ratio, held, sources)
    names = [term_name(ratio, p) for p in ("num", "den")]
    kept = None if path is None else _read(path, held, names)
    if kept is not None:
        return kept
    parts = [_compute(store, ratio, held, sources, runs) for runs in _run_parts(store)]
    return pl.concat(parts, how="vertical")


def _selected(
    store: Store, kept: pl.DataFrame, columns: Sequence[str], where: Filters
) -> pl.DataFrame:
    """`columns` of the kept rows that `where` selects, in the kept order; a filter on a
    held column or run_id is bound as the tables' query binds it (`_filter_condition`, the
    column's type in the episodes table), one on a run column through the runs table."""
    if not where:
        return kept.select(columns)
    params: list[object] = []
    conditions = []
    on_runs = []
    for column, value in where.items():
        if column in kept.columns:
            sql_type = store.columns[EPISODES_TABLE][column]
            expr = f"g.{quote_ident(column)}"
            conditions.append(_filter_condition(expr, sql_type, value, params))
        else:
            sql_type = store.columns[RUNS_TABLE][column]
            expr = f"r.{quote_ident(column)}"
            on_runs.append(_filter_condition(expr, sql_type, value, params))
    if on_runs:
        conditions.append(
            f"g.run_id IN (SELECT r.run_id FROM runs AS r WHERE {' AND '.join(on_runs)})"
        )
    select = ", ".join(f"g.{quote_ident(c)}" for c in columns)
    sql = f"SELECT {select} FROM __episode_terms AS g WHERE {' AND '.join(conditions)}"
    table = kept.select(columns).to_arrow()
    derived = dataclasses.replace(store, sources={**store.sources, "__episode_terms": table})
    return run_query(derived, sql, params)


def keep_episode_terms(store: Store, ratio: Ratio, sources: Sequence[str]) -> None:
    """Compute and keep the terms per (run, episode) of `ratio` unless a valid file holds
    them: what the metric cache adds when it writes the per-run terms of the episodes
    (`_cache`), for the set's first metric of the episodes (SR's, the Leaderboard's first
    interval), so that `vge metrics OUT`, run first, also fills what that reads (written a
    part at a time, never read back here). Nothing when OUT keeps nothing, the terms cannot
    be had (the command has its answer already), or a metric file's query would run in a
    process of its own for each part (a server's; its intervals read the tables then)."""
    bounds = query_bounds()
    if bounds is not None and bounds.isolated and sources:
        return
    with contextlib.suppress(OSError, duckdb.Error, pl.exceptions.PolarsError, QueryError):
        _keep(store, ratio, _held(store), sources)


def kept_episode_terms(
    store: Store,
    ratio: Ratio,
    by: Sequence[str],
    where: Filters,
    *,
    files_of: Callable[[Sequence[Ratio]], Sequence[str]] = lambda ratios: (),
) -> pl.DataFrame | None:
    """run_id, episode_id, the episodes' columns of `EPISODE_COLUMNS` and `by`, and the terms
    of `ratio` (`<name>:num`, `<name>:den`), one row per episode `where` selects that has
    terms: from its terms kept beside OUT (computed and kept first when missing), or None
    when they cannot answer (OUT keeps nothing, a column of `by` or `where` that is not
    one of those, a metric file's terms in a process of its own, a term that fails)."""
    held = _held(store)
    columns = [*by, *(where or {})]
    bounds = query_bounds()
    isolated = bounds is not None and bounds.isolated and bool(files_of([ratio]))
    if isolated or not _answers(store, columns, held):
        return None
    kept = unless_failed(lambda: _kept_table(store, ratio, held, files_of([ratio])))
    if kept is None:
        return None
    wanted = [*_KEYS, *held, *(c for c in by if c in held and c not in _KEYS)]
    wanted = list(dict.fromkeys(wanted))
    return _selected(
        store, kept, [*wanted, term_name(ratio, "num"), term_name(ratio, "den")], where
    )


__all__ = ["EPISODE_COLUMNS", "MAX_TERMS_BYTES", "MAX_TERMS_FILES", "kept_episode_terms"]
