"""The metric cache: the metrics' terms per run, computed once per OUT and kept beside it.

Every metric is `scale * sum(numerator) / sum(denominator)` over the rows of its grain, both
terms additive (PROTOCOL §6). A grouping by run columns (run_id, model, agent_kind, a facet)
is already computed in two levels (`grouped_aggregate`): each run's terms over the big table,
then those few rows added up per group. The cache keeps the first level: the first such
computation over a grain scans that table once for every metric of the set on it and writes
one row per run (run_id, each metric's numerator and denominator, exactly the values the
first level computes) to `OUT/.metric-cache/<grain>-<manifest>-<definitions>.parquet`
(`replay.io.metric_cache_path`); later computations add those rows up as the second level
does, so their values are the same bits. (Per-episode terms would serve groupings by episode
columns too, but a distance summed per episode and then over episodes rounds differently,
in its last bit, from one compensated sum over the steps: measured on the sample.)

The file's name holds what it was computed from: a hash of OUT's contents (the sha256 of its
manifest, which every replay rewrites with its inputs' sha256, options and engine version,
and the size and modification time of every table file) and a hash of the definitions
(name, grain, numerator, denominator) of the metrics in it. A change to either
names another file: nothing stale is ever read. When a file is written, the files of that
grain made from another manifest are removed (they can never be read again).

The cache answers only what it answers with the same bits: a local OUT with a manifest,
grouped by run_id or by a column fixed per run, filtered on such columns; anything else
(a column of episodes, steps or goals, no run column at all) reads the tables as before.
A file is written whole or not at all (`replay.io.atomic_file`); when OUT cannot be written
(read-only, full), or the terms cannot be computed, nothing is cached and the query runs on
the tables.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import json
from collections.abc import Callable, Sequence
from pathlib import Path

import duckdb
import pyarrow as pa
import pyarrow.parquet as pq

from replay.io import EPISODES_TABLE, atomic_file, metric_cache_path

from .._errors import QueryError, QueryLimitError
from ._bounds import query_bounds
from ._kept import own_folder
from ._ratios import Ratio, ratio_terms, term_name
from ._scope import Filters, grouped_aggregate, quote_ident, run_level
from ._sql import run_query
from ._store import Store

CACHE_ROW_GROUP = 65_536
"""Rows per row group of a cache file (a row per run: one group but for thousands of runs)."""


def definitions_key(ratios: Sequence[Ratio]) -> str:
    """A hash of what the terms of `ratios` are computed from."""
    doc = [[r.name, r.grain, r.numerator, r.denominator] for r in ratios]
    return hashlib.sha256(json.dumps(doc).encode()).hexdigest()[:16]


def _cacheable(store: Store, grain: str, by: Sequence[str], where: Filters) -> bool:
    """Whether the query grouping `grain` rows by `by`, filtered by `where`, adds up per-run
    terms: every column run_id or fixed per run, and run_id or such a column among them
    (without, the rows of every run are summed at once, in one level)."""
    columns = [*by, *(where or {})]
    per_run = [c for c in columns if run_level(store, grain, c)]
    return all(c == "run_id" or c in per_run for c in columns) and ("run_id" in by or bool(per_run))


def _where(store: Store) -> Path | None:
    """The local OUT whose terms may be cached, or None (in memory, in object storage,
    without a manifest, or its cache folder a link)."""
    if store.contents is None or not isinstance(store.out, Path) or not own_folder(store.out):
        return None
    return store.out


def _write(
    store: Store, grain: str, ratios: Sequence[Ratio], path: Path, sources: Sequence[str]
) -> None:
    """Compute the per-run terms of `ratios` over `grain` and write them to `path`: one query
    as any other of the analytics (`run_query`, within the bounds of the block around it;
    `sources`, the metric files it holds, named if it is stopped); its result is a row a run."""
    sql, params = grouped_aggregate(store, grain, ("run_id",), None, ratio_terms(ratios))
    sql += " ORDER BY run_id"
    table = run_query(store, sql, params, sources=sources).to_arrow()
    path.parent.mkdir(exist_ok=True)
    with atomic_file(path, sync=False) as fh:
        pq.write_table(table, fh, row_group_size=CACHE_ROW_GROUP)
    for old in path.parent.glob(f"{grain}-*.parquet"):  # made from another manifest: dead
        if old.name.split("-")[1] != path.name.split("-")[1]:
            with contextlib.suppress(OSError):
                old.unlink()


def _read(path: Path, names: Sequence[str]) -> pa.Table | None:
    """The cache file at `path` if it holds the keys and every term in `names`, else None
    (read whole: a row per run; its run_id as a dictionary, as the tables' is)."""
    try:
        with pq.ParquetFile(path, read_dictionary=["run_id"]) as file:  # not pq.read_table,
            data = file.read()  # which imports pyarrow's dataset module, and pandas with it
    except (OSError, pa.ArrowException):
        return None
    schema = data.schema
    wanted = ["run_id", *names]
    if any(schema.get_field_index(n) < 0 for n in wanted):
        return None
    numeric = all(
        pa.types.is_integer(schema.field(n).type)
        or pa.types.is_floating(schema.field(n).type)
        or pa.types.is_decimal(schema.field(n).type)
        for n in names
    )
    return data if numeric else None


def _terms_source(
    store: Store,
    grain: str,
    ratio_set: Sequence[Ratio],
    out: Path,
    key: str,
    sources: Sequence[str],
) -> pa.Table | None:
    """The cached per-run terms of every ratio of `ratio_set` over `grain` (computed and written
    first when missing), or None when they cannot be had."""
    names = [term_name(r, p) for r in ratio_set for p in ("num", "den")]
    path = metric_cache_path(out, grain, key, definitions_key(ratio_set))
    data = _read(path, names) if path.is_file() else None
    if data is not None:
        return data
    try:
        _write(store, grain, ratio_set, path, sources)
    except QueryLimitError:
        raise  # a bound stopped it: the tables would be stopped the same way
    except (OSError, duckdb.Error, pa.ArrowException, QueryError):
        return None  # read-only or full OUT, or a term that fails: the tables answer
    if grain == EPISODES_TABLE and ratio_set:  # and the first metric's terms per episode,
        from ._episode_terms import keep_episode_terms  # the Leaderboard's first interval

        keep_episode_terms(store, ratio_set[0], sources)
    return _read(path, names)


def cached_store(
    store: Store,
    ratios: Sequence[Ratio],
    ratio_set: Sequence[Ratio],
    by: Sequence[str],
    where: Filters,
    *,
    files_of: Callable[[Sequence[Ratio]], Sequence[str]] = lambda ratios: (),
) -> tuple[Store, dict[str, str]]:
    """`store` with the cached per-run terms of each grain of `ratios` that can answer
    grouping `by` and filtering `where` (as tables `__terms_<grain>`), and {grain: table}.
    `ratio_set`: every ratio whose terms a cache file holds (a superset of `ratios`, so that
    any choice among them reads one file per grain). `files_of`: the metric files that define
    some ratios (named when a bound stops the query computing their terms)."""
    out = _where(store)
    bounds = query_bounds()
    if out is None or (bounds is not None and bounds.isolated and files_of(ratios)):
        # (a server runs a query holding a metric file's SQL in a process of its own, which
        # opens OUT afresh, without the cache's tables: there the tables answer)
        return store, {}
    key = store.contents
    sources: dict[str, object] = {}
    for grain in dict.fromkeys(r.grain for r in ratios):
        if not _cacheable(store, grain, by, where):
            continue
        on_grain = [r for r in ratio_set if r.grain == grain]
        data = _terms_source(store, grain, on_grain, out, key, files_of(on_grain))
        if data is not None:
            sources[f"__terms_{grain}"] = data
    if not sources:
        return store, {}
    derived = with_tables(store, sources)
    return derived, {name.removeprefix("__terms_"): name for name in sources}


def with_tables(store: Store, tables: dict[str, object]) -> Store:
    """`store` with `tables` (Arrow tables, by our own names) added to its sources and its
    catalogue of columns, so that they can be grouped and filtered as its tables are."""
    derived = dataclasses.replace(store, sources={**store.sources, **tables})
    catalogue: dict[str, dict[str, str]] = {}
    for name in tables:
        statement = f"DESCRIBE {name}"  # our own names
        with derived.cursor(statement) as cursor:
            rows = cursor.execute(statement).fetchall()
        catalogue[name] = {r[0]: str(r[1]) for r in rows}
    derived.columns = {**store.columns, **catalogue}
    return derived


def cached_terms(ratios: Sequence[Ratio]) -> list[tuple[str, str]]:
    """The aggregate terms of `ratios` over a cache table: the runs' terms added
    up with `sum`, as the second level of `grouped_aggregate` adds them."""
    names = [term_name(r, part) for r in ratios for part in ("num", "den")]
    return [(f"coalesce(sum({quote_ident(n)}), 0)", n) for n in names]


__all__ = [
    "cached_store",
    "cached_terms",
    "definitions_key",
    "with_tables",
]
