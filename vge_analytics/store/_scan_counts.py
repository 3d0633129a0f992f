"""The scored steps counted per group by polars, from the steps table's files themselves.

The step counts kept beside OUT (`_step_counts`) are counted once per OUT, at a page's first
visit, per run and category: 182,500 groups for the errors, 2 million for the clicked views
at 100 times the full benchmark. DuckDB over the Arrow dataset took longer for them than
the page's own query had (whose groups were fewer), 1.2 to 3 s more; polars' Parquet reader
and grouping count the same rows with less work (docs/PERFORMANCE.md, *The first server at
100x*). The files are the dataset's (OUT's own, listed from its manifest and checked to lie
inside it, `_datasets`), each path opened as it is, never as a pattern.

Used only where it gives the rows DuckDB's query gives: a local OUT whose steps table is
files, each in its run's folder (`run_id=<run>`, the run the dataset gives its rows, read by
polars from the path), every column counted of the type the replay writes (the keys strings,
the conditions booleans). Anything else, or a file polars cannot read as those types,
answers None: the caller asks DuckDB, as before.

Its bounds: the time limit of the block around it (`query_limits`), looked at between
chunks of whole runs (`CHUNK_FILES` files or more: 22 chunks at 100x): past it the count
stops with `QueryLimitError`, as DuckDB's query would be stopped. (polars' own background
query, which could be cancelled at any time, took 4 to 5 times the CPU.) Its memory is
polars' streaming engine's: a chunk's groups and a few row groups of the counted columns at
a time, and the counts (the result: what DuckDB's result holds too), not DuckDB's memory
limit (peak RSS at 100x: 1.1 GB, as 6285fcc's query of the page; DuckDB's count, 1.8 GB).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Collection, Sequence
from time import monotonic

import polars as pl

from replay.io import PARTITION_KEY, STEPS_TABLE, partition

from .._errors import QueryLimitError
from ._bounds import query_bounds
from ._datasets import local_files
from ._limits import SqlLimits
from ._sql import query_limits_of, subject_of, time_message
from ._store import Store

CHUNK_FILES = 128
"""Files counted at a time (whole runs, in order): the time limit is looked at between them."""


def _runs(store: Store) -> list[tuple[str, list[str]]] | None:
    """(run, paths of its files) of the steps table's files on the local disk, sorted by
    run, or None (in memory, in object storage, no file, or a file whose run polars would
    not read from its path as the dataset has it, `_in_its_folder`)."""
    files = local_files(store.sources.get(STEPS_TABLE))
    if files is None:
        return None
    runs: dict[str, list[str]] = {}
    for run, path in files:
        if not isinstance(run, str) or not _in_its_folder(path, run):
            return None
        runs.setdefault(run, []).append(path)
    return sorted(runs.items()) or None


def _in_its_folder(path: str, run: str) -> bool:
    """Whether polars reads `run` from `path` as its run_id (`hive_partitioning`): the file
    in a folder `run_id=<run>`, no other `=` in its path (polars would read each as a
    column), no `%` in the run (polars would decode it)."""
    folder, name = os.path.split(path)
    above, folder = os.path.split(folder)
    return folder == partition(run) and "%" not in run and "=" not in above + name


def _chunks(runs: list[tuple[str, list[str]]]) -> list[tuple[set[str], list[str]]]:
    """`runs` cut into chunks of whole runs, in order, of `CHUNK_FILES` files or more."""
    chunks: list[tuple[set[str], list[str]]] = []
    for run, paths in runs:
        if not chunks or len(chunks[-1][1]) >= CHUNK_FILES:
            chunks.append((set(), []))
        chunks[-1][0].add(run)
        chunks[-1][1].extend(paths)
    return chunks


def _schema(store: Store, keys: Sequence[str], flags: Sequence[str]) -> dict | None:
    """The polars types of the columns counted, or None unless they are the replay's: the
    keys strings, the flags booleans (as DuckDB sees the tables)."""
    columns = store.columns[STEPS_TABLE]
    if any(columns.get(k) != "VARCHAR" for k in keys):
        return None
    if any(columns.get(f) != "BOOLEAN" for f in flags):
        return None
    return {**dict.fromkeys(keys, pl.String), **dict.fromkeys(flags, pl.Boolean)}


def _deadline(store: Store) -> tuple[float | None, SqlLimits]:
    """When the count must end (`monotonic`; None: never), and the limits saying so."""
    bounds = query_bounds()
    limits = query_limits_of(store, bounds.limits if bounds is not None else None)
    return (None if limits.timeout is None else monotonic() + limits.timeout), limits


def _counter(
    schema: dict, keys: list[str], name: str, where: str | None, only: str | None
) -> Callable[[list[str]], pl.DataFrame]:
    """What counts the scored steps of some files, per `keys`, sorted by them."""
    scored = ~pl.col("truncated")
    if where is not None:
        scored = scored & pl.col(where)  # null is not true: dropped, as in SQL
    count = pl.len() if only is None else pl.col(only).sum()  # trues; a group of none: 0
    options = pl.ScanCastOptions(categorical_to_string="allow")

    def counted(paths: list[str]) -> pl.DataFrame:
        scanned = pl.scan_parquet(
            paths,
            schema={k: v for k, v in schema.items() if k != PARTITION_KEY},
            hive_partitioning=True,  # run_id: the file's run, as the dataset has it
            hive_schema={PARTITION_KEY: pl.String},
            glob=False,  # a path is a name, not a pattern (an OUT named `out[12]`)
            missing_columns="insert",  # as the dataset unifies the files: null there
            extra_columns="ignore",
            cast_options=options,
        )
        return (
            scanned.filter(scored)
            .group_by(keys)
            .agg(count.cast(pl.Int64).alias(name))
            .sort(keys, nulls_last=True)
            .collect(engine="streaming")
        )

    return counted


def count_steps(
    store: Store,
    keys: Sequence[str],
    name: str,
    where: str | None,
    only: str | None,
    of_runs: Collection[str] | None = None,
) -> pl.DataFrame | None:
    """The scored steps of OUT (`truncated` false) where the boolean column `where` is true
    (None: all), per `keys` (run_id first), their number as `name` (of those where `only` is
    true, None: all), sorted by `keys`, nulls last: the rows of `_step_counts._query`. None
    where polars cannot give them (the caller counts in DuckDB).

    Counted a chunk of whole runs at a time, in the runs' order, each file's run_id its run
    (the dataset's partition, whatever the file holds), read from its folder's name: each
    chunk's rows are its runs' (checked), so the chunks, each sorted, are the sorted whole.
    Past the block's time limit, between chunks, the count stops with `QueryLimitError`.
    `of_runs`: only these runs' files are read (None: all; the rows of the query `WHERE
    run_id IN of_runs`), the others not opened."""
    runs = _runs(store)
    if runs is not None and of_runs is not None:
        wanted = set(of_runs)
        runs = [(run, paths) for run, paths in runs if run in wanted] or None
    flags = ["truncated", *(c for c in (where, only) if c is not None)]
    schema = _schema(store, keys, flags)
    if runs is None or schema is None:
        return None
    counted = _counter(schema, list(keys), name, where, only)
    end, limits = _deadline(store)
    parts = []
    for held, paths in _chunks(runs):
        if end is not None and monotonic() > end:
            raise QueryLimitError(time_message(subject_of(store.out, ()), limits), limit="time")
        try:
            part = counted(paths)
        except (OSError, pl.exceptions.PolarsError):
            return None
        if not set(part[PARTITION_KEY].unique().to_list()) <= held:  # read otherwise: DuckDB
            return None
        parts.append(part)
    return pl.concat(parts, rechunk=True)


__all__ = ["count_steps"]
