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

Its bounds are the store's queries': it runs in a query process of its own (`_isolated`'s,
forked from the forkserver, taking one of the process slots), its data segment capped for
its life at its size (polars' threads started) plus the memory limit in force and half again
(`process_memory_cap`, `memory_headroom`; `query_limits_of`: the block's, else the store's),
as DuckDB's query would be bounded by that memory limit. The steps a hand-made OUT may hold
are what polars cannot bound itself: a million error types (a group each: its sort reserves
3.5 GB for them), one error type of 100 KB on 40,000 steps (a file of 270 KB: polars copies
the key per step, 0.95 GB). Such a count reaches the cap and its process ends there (polars
aborts where an allocation fails: that is why it is not run in this one, which serves a
dashboard's other visitors), this process's memory untouched: the count is DuckDB's query's
then, the same rows, within its memory limit or stopped by it with the usual line. A bound
by the Parquet footers (each row group's uncompressed bytes of the counted columns) was not
enough: that error type's column is 100 KB uncompressed (its dictionary), for 0.95 GB.

The time limit of the block (`query_limits`) is looked at between chunks of whole runs
(`CHUNK_FILES` files or more: 22 chunks at 100x); past it the count stops with
`QueryLimitError`, as DuckDB's query would be stopped, and a process silent past it (a chunk
that does not end) is killed. (polars' own background query, which could be cancelled at any
time, took 4 to 5 times the CPU.) Each chunk's counts are sent back as soon as counted, as
polars' IPC stream, what this process holds of them bounded by the same memory limit and
half again. At 100x the count's process peaks at 0.15 to 0.33 GB; the views' 2 million rows
take 0.5 to 0.6 CPU s more to hand over (their first count 1.04 to 1.31 times c959cdc's CPU,
in this process then; the others' at parity: docs/PERFORMANCE.md, *The first count's memory
bound*). A process that has not started the forkserver yet (a command's first count; the
dashboard starts it with the server) waits for it too: 0.6 to 0.8 s more on the bundled
sample, 5 s under a heavy load.
"""

from __future__ import annotations

import contextlib
import io
import os
import resource
from collections.abc import Callable, Collection, Sequence
from multiprocessing.connection import Connection
from multiprocessing.process import BaseProcess
from time import monotonic
from typing import NamedTuple

import polars as pl

from replay.io import PARTITION_KEY, STEPS_TABLE, partition

from .._errors import QueryLimitError
from ._bounds import query_bounds
from ._datasets import run_files
from ._isolated import GRACE, _slots, _start
from ._limits import (
    SqlLimits,
    data_segment,
    default_max_queries,
    memory_headroom,
    process_memory_cap,
)
from ._sql import query_limits_of, subject_of, time_message
from ._store import Store

CHUNK_FILES = 128
"""Files counted at a time (whole runs, in order): the time limit is looked at between them."""

POLARS_FROM_BYTES = 1 << 30
"""Steps files (their bytes on disk, of the runs counted) from which polars counts them, in
its process; below, DuckDB's query, as quick or quicker without a process to start (first
error shares, wall: the bundled sample 0.30 s against 1.26, the full benchmark's 52 MB 0.37
against 1.28, 10 times it, 0.8 GB, 0.53 to 0.60 against 1.02 to 1.11; at 100 times, 7.7 GB,
polars takes a fifth to a third less CPU for the same wall time: docs/PERFORMANCE.md, *The
first count's memory bound*)."""


def _runs(store: Store) -> list[tuple[str, list[str]]] | None:
    """(run, paths of its files) of the steps table's files on the local disk, sorted by
    run, or None (in memory, in object storage, no file, or a file whose run polars would
    not read from its path as the dataset has it, `_in_its_folder`)."""
    files = run_files(store.sources.get(STEPS_TABLE))
    if files is None or not all(_in_its_folder(p, run) for run, ps in files.items() for p in ps):
        return None
    return sorted(files.items()) or None


def _in_its_folder(path: str, run: str) -> bool:
    """Whether polars reads `run` from `path` as its run_id (`hive_partitioning`): the file
    in a folder `run_id=<run>`, no other `=` in its path (polars would read each as a
    column), no `%` in the run (polars would decode it)."""
    folder, name = os.path.split(path)
    above, folder = os.path.split(folder)
    return folder == partition(run) and "%" not in run and "=" not in above + name


def _size(runs: list[tuple[str, list[str]]]) -> int:
    """The bytes of the files of `runs` (a file that cannot be looked at: none)."""
    size = 0
    for _, paths in runs:
        for path in paths:
            with contextlib.suppress(OSError):
                size += os.stat(path).st_size
    return size


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


def _count(
    chunks: list[tuple[set[str], list[str]]],
    counted: Callable[[list[str]], pl.DataFrame],
    end: float | None,
    stop: Callable[[], QueryLimitError],
    keep: Callable[[pl.DataFrame], object],
) -> bool:
    """Count `chunks`, one after the other, each chunk's counts handed to `keep` as soon as
    counted; False where polars cannot read them as the dataset has them. Past `end`
    (`monotonic`), between two chunks, raises `stop()`."""
    for n, (held, paths) in enumerate(chunks):
        if n and end is not None and monotonic() > end:
            raise stop()
        try:
            part = counted(paths)
        except (OSError, pl.exceptions.PolarsError):
            return False
        if not set(part[PARTITION_KEY].unique().to_list()) <= held:  # read otherwise: DuckDB
            return False
        keep(part)
    return True


class CountProcess(NamedTuple):
    """What the last count's process answered (for benchmarks and tests; None before any)."""

    counted: bool
    """polars gave the rows (False: the caller counts in DuckDB)."""
    cpu_seconds: float
    """CPU time of the process (0: it ended without an answer, past its cap)."""
    peak_memory: int
    """Its peak resident memory, bytes (0: as above)."""
    room: int = 0
    """What its cap let its data segment grow by when set, bytes (0: as above)."""


last_process: CountProcess | None = None


class _Job(NamedTuple):
    """What the count's process is handed: the chunks, what it counts, when it must end."""

    chunks: list[tuple[set[str], list[str]]]
    schema: dict
    keys: list[str]
    name: str
    where: str | None
    only: str | None
    end: float | None
    limits: SqlLimits
    subject: str


def _count_child(conn: Connection, job: _Job) -> None:
    """The count's process: count `job` within its process cap, sending each chunk's counts
    as soon as counted (`("part",)`, then polars' IPC stream: the parent reads one while the
    next is counted), then `("ok", counted, CPU seconds, peak memory, room)` or `("error",
    message)`, and exit. Past the cap an allocation fails: polars' aborts the process (no core
    file, its message not printed), Python's (MemoryError) answers `("ok", False, ...)`."""
    resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
    os.dup2(os.open(os.devnull, os.O_WRONLY), 2)
    with conn, process_memory_cap(job.limits):  # (polars' threads started before the cap)
        room = resource.getrlimit(resource.RLIMIT_DATA)[0] - data_segment()
        counted = _counter(job.schema, job.keys, job.name, job.where, job.only)

        def stop() -> QueryLimitError:
            return QueryLimitError(time_message(job.subject, job.limits), limit="time")

        def send(part: pl.DataFrame) -> None:
            stream = io.BytesIO()
            part.write_ipc_stream(stream, compat_level=pl.CompatLevel.newest())
            conn.send(("part",))
            conn.send_bytes(stream.getbuffer())

        try:
            whole = _count(job.chunks, counted, job.end, stop, send)
        except QueryLimitError as exc:
            conn.send(("error", str(exc)))
            return
        except MemoryError:
            whole = False
        used = resource.getrusage(resource.RUSAGE_SELF)
        conn.send(("ok", whole, used.ru_utime + used.ru_stime, used.ru_maxrss * 1024, room))


def _receive(child: BaseProcess, receiver: Connection, job: _Job) -> list[pl.DataFrame] | None:
    """The counts the count's process sends, chunk by chunk, or None: it found files polars
    cannot read as the dataset has them, it ended without answering (past its cap), or its
    counts passed the memory limit and half again (`memory_headroom`). Past the time limit
    and a grace period it is killed; it has ended when this returns."""
    global last_process
    parts: list[pl.DataFrame] = []
    room = memory_headroom(job.limits)
    last_process = CountProcess(False, 0.0, 0)
    try:
        while True:
            wait = None if job.end is None else max(job.end - monotonic(), 0.0) + GRACE
            if not receiver.poll(wait):
                raise QueryLimitError(time_message(job.subject, job.limits), limit="time")
            message = receiver.recv()
            if message[0] == "error":
                raise QueryLimitError(message[1], limit="time")
            if message[0] == "ok":
                last_process = CountProcess(*message[1:])
                return parts if message[1] else None
            data = receiver.recv_bytes(maxlength=max(room, 1))
            room -= len(data)
            parts.append(pl.read_ipc_stream(io.BytesIO(data)))
    except (EOFError, OSError):  # ended, or sent more than the room left: DuckDB's then
        return None
    finally:
        receiver.close()
        if child.is_alive():
            child.kill()
        child.join()


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
    where polars cannot give them (the caller counts in DuckDB): files it cannot read as the
    dataset has them, a count past its process's memory cap, no query process free, or
    files under `POLARS_FROM_BYTES` in all (DuckDB's query is quicker there).

    Counted in a query process of its own (`_count_child`), capped for its life as the
    store's queries are (`process_memory_cap`), a chunk of whole runs at a time, in the
    runs' order, each file's run_id its run (the dataset's partition, whatever the file
    holds), read from its folder's name: each chunk's rows are its runs' (checked), so the
    chunks, each sorted, are the sorted whole. Past the block's time limit, between chunks,
    the count stops with `QueryLimitError`. `of_runs`: only these runs' files are read
    (None: all; the rows of the query `WHERE run_id IN of_runs`), the others not opened."""
    runs = _runs(store)
    if runs is not None and of_runs is not None:
        wanted = set(of_runs)
        runs = [(run, paths) for run, paths in runs if run in wanted] or None
    flags = ["truncated", *(c for c in (where, only) if c is not None)]
    schema = _schema(store, keys, flags)
    if runs is None or schema is None or _size(runs) < POLARS_FROM_BYTES:
        return None
    end, limits = _deadline(store)
    subject = subject_of(store.out, ())
    job = _Job(_chunks(runs), schema, list(keys), name, where, only, end, limits, subject)
    bounds = query_bounds()
    slots = _slots((bounds.max_queries if bounds else None) or default_max_queries(limits))
    if not slots.acquire(blocking=False):
        return None  # every query process taken: DuckDB's query now, bounded by its limit
    try:
        parts = _receive(*_start(_count_child, (job,)), job)
    except OSError:  # no process could be started (out of memory or processes): DuckDB's
        parts = None
    finally:
        slots.release()
    return None if parts is None else pl.concat(parts, rechunk=True)


__all__ = ["count_steps"]
