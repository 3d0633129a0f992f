"""One user query in a process of its own (the dashboard's SQL page, and each query of its
pages that holds a metric file's SQL).

The dashboard serves every visitor from one process, so a query run inside it could take all
of it down: DuckDB's memory limit does not cover everything (one value larger than memory,
`repeat('x', 10^10)`), its parser takes hundreds of times the text's size, and a query that
ignores its interrupt would hold a thread forever. Here each query is parsed, checked and run
in a child process forked from a forkserver (it starts in milliseconds, with the libraries
already imported), with DuckDB's limits and its data segment capped (`process_memory_cap`,
for the child's whole life). The server only measures the text (`check_size`). The child
sends back the first rows as Arrow IPC, cut to what a page holds (`bound_result`: the
server never holds more of a result than `RESULT_BYTES`), or the one-line error. The parent
waits for the time limit plus a grace period and kills a child that has not answered by
then; a child that dies (killed, crashed) is reported, and the next query gets a fresh child.

The pages' queries that hold SQL a user wrote (a metric file of `vge app --metrics-dir`) run
the same way (`query_isolated`, chosen by `run_query` within `query_limits(...,
isolated=True)`): the child opens OUT within the limits (or is handed the Arrow tables of a
sweep's `memory_store`), runs the query through `run_query`, and sends back the whole result.

At most `max_queries` children run at once across all the sessions of the server (each may
take its memory limit and half again), SQL page and metric queries together: a query beyond
them waits up to `SLOT_WAIT` seconds for one to end, then is refused in one line.

A server that keeps a standby for OUT (`_standby`: `vge app`) runs the SQL page's query in
it, a child forked ahead of need with OUT already open, when it is fresh; otherwise in a new
child, as above.
"""

from __future__ import annotations

import multiprocessing
import resource
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from functools import cache
from multiprocessing.connection import Connection
from multiprocessing.process import BaseProcess
from pathlib import Path
from typing import TYPE_CHECKING

import polars as pl
import pyarrow as pa

from .._errors import AnalyticsError, OutputDirError, QueryError, QueryLimitError, QueryRefused
from ._limits import (
    SLOT_WAIT,
    SqlLimits,
    default_max_queries,
    format_size,
    memory_headroom,
    process_memory_cap,
)
from ._page_result import ResultCut, bound_result
from ._sql import check_size, memory_message, sql_head, subject_of, time_message
from ._store import Store, memory_store, open_store

if TYPE_CHECKING:
    from ._bounds import QueryBounds

GRACE = 5.0
"""Seconds the parent waits past the time limit before it kills the child (the child's own
timer normally ends the query first, with a clearer message)."""

_CONTEXT = multiprocessing.get_context("forkserver")
_PRELOAD = [__name__, "pyarrow.dataset"]
"""What the forkserver imports once for all its children: this module (polars, pyarrow,
DuckDB) and pyarrow's dataset module, which a child needs to scan OUT's tables and which
imports pandas (0.5 s idle, 1.4 s under load, in every child before)."""
_ERRORS = {cls.__name__: cls for cls in (QueryError, QueryRefused, QueryLimitError, OutputDirError)}


@dataclass(frozen=True)
class IsolatedResult:
    """The first rows of a query run in its own process."""

    frame: pl.DataFrame
    truncated: bool
    """The result has more rows than `frame` holds."""
    seconds: float
    """Wall time of the query, process start included."""
    peak_memory: int
    """Peak resident memory of the query's process (bytes)."""
    cut: ResultCut = ResultCut()
    """What the query process cut from those rows to fit a page (`bound_result`)."""
    pid: int = 0
    """The id of the query's process."""
    standby: bool = False
    """The query ran in the standby process of OUT (`_standby`), not in one started for it."""


def warm_query_processes() -> None:
    """Start the forkserver now (it imports the libraries once), not on the first query."""
    _CONTEXT.set_forkserver_preload(_PRELOAD)
    from multiprocessing import forkserver

    forkserver.ensure_running()


@cache
def _slots(size: int) -> threading.BoundedSemaphore:
    """The process slots of this server for a cap of `size` (one cap per server in practice:
    `vge app --sql-max-queries`)."""
    return threading.BoundedSemaphore(size)


def _peak_memory() -> int:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def _send_frame(conn: Connection, frame: pl.DataFrame, *header: object) -> None:
    """Answer with `("ok", *header, peak memory)`, then the frame as Arrow IPC."""
    table = frame.to_arrow()
    sink = pa.BufferOutputStream()
    with pa.ipc.new_stream(sink, table.schema) as writer:
        writer.write_table(table)
    conn.send(("ok", *header, _peak_memory()))
    conn.send_bytes(sink.getvalue())


def _answer_failure(conn: Connection, exc: BaseException, limits: SqlLimits, subject: str) -> None:
    """Answer with `("error", kind, message, limit, peak memory)`."""
    if isinstance(exc, MemoryError):
        message, kind, limit = memory_message(subject, limits), "QueryLimitError", "memory"
    else:  # refused, failed, stopped, or OUT unreadable
        message, kind, limit = str(exc), type(exc).__name__, getattr(exc, "limit", None)
    conn.send(("error", kind, message, limit, _peak_memory()))


def answer_query(conn: Connection, out: str, query: str, rows: int, limits: SqlLimits) -> None:
    """Run the SQL page's query over OUT within `limits` and answer once (in a query process,
    capped already: a fresh one, `_child`, or the standby, `_standby`)."""
    try:
        head = sql_head(out, query, rows, limits=limits)
        frame, cut = bound_result(head.frame)
        _send_frame(conn, frame, head.truncated, cut)
    except (AnalyticsError, MemoryError) as exc:
        _answer_failure(conn, exc, limits, "the query")


def _child(conn: Connection, out: str, query: str, rows: int, limits: SqlLimits) -> None:
    """The SQL page's query process: run the query within its limits, answer once, exit."""
    with conn, process_memory_cap(limits):
        answer_query(conn, out, query, rows, limits)


@dataclass(frozen=True)
class _Tables:
    """What a query process opens: OUT (`out`), or the tables of a `memory_store` (`held`,
    named in messages by `out`)."""

    out: object
    held: dict[str, pa.Table] | None = None


def _query_child(
    conn: Connection,
    where: _Tables,
    sql: str,
    params: list,
    limits: SqlLimits,
    sources: tuple[str, ...],
) -> None:
    """An analytics query's process (`query_isolated`): open OUT (or the tables handed over)
    within `limits`, run the query there, capped for the process's life; answer once."""
    from ._bounds import within
    from ._sql import run_query

    with conn, process_memory_cap(limits):
        try:
            if where.held is not None:
                store = memory_store(where.held, label=where.out, limits=limits)
            else:
                store = open_store(where.out, limits)
            with within(limits):  # this process is capped already, for its life
                frame = run_query(store, sql, params, sources=sources)
            _send_frame(conn, frame)
        except (AnalyticsError, MemoryError) as exc:
            _answer_failure(conn, exc, limits, subject_of(where.out, sources))


def _error(kind: str, message: str, limit: str | None) -> Exception:
    cls = _ERRORS.get(kind, QueryError)
    if cls is QueryLimitError:
        return QueryLimitError(message, limit=limit or "memory")
    return cls(message)


def _slot(size: int, prefix: str = "") -> threading.BoundedSemaphore:
    """A process slot of this server, taken (release it); refused past `SLOT_WAIT` seconds
    with a line that begins with `prefix`."""
    slots = _slots(size)
    if not slots.acquire(timeout=SLOT_WAIT):
        raise QueryLimitError(
            f"{prefix}{size} {'query is' if size == 1 else 'queries are'} running already, as "
            f"many as the dashboard runs at once; this one waited {SLOT_WAIT:g} s: run it "
            "again when one has ended",
            limit="queries",
        )
    return slots


def run_isolated(
    out: str | Path,
    query: str,
    rows: int,
    limits: SqlLimits,
    *,
    max_queries: int | None = None,
) -> IsolatedResult:
    """The first `rows` rows of a read-only query over OUT, computed in a child process
    within `limits`, while at most `max_queries` such processes run in this server (default:
    `default_max_queries(limits)`): the standby of OUT when this server keeps one and it is
    fresh (`_standby`; a new one is started after), else a new child. Raises `QueryRefused`,
    `QueryLimitError` or `QueryError` (one line)."""
    from . import _standby

    check_size(query)  # too large: refused without a process; parsing is the child's job
    slots = _slot(max_queries or default_max_queries(limits))
    started = time.monotonic()
    try:
        standby = _standby.take(out, limits)
        answer = None if standby is None else standby.ask(query, rows)
        if answer is None:  # no standby, a stale or dead one: a new child, as without one
            child, conn = _start(_child, (str(out), query, rows, limits))
            header, data = _answer(child, conn, limits, "the query")
            pid = child.pid
        else:
            (header, data), pid = answer, standby.pid  # type: ignore[union-attr]
    finally:
        slots.release()
        _standby.renew(out)  # (after the query: it does not take the query's CPU)
    _, truncated, cut, peak = header
    return IsolatedResult(
        frame=_frame(data),
        truncated=truncated,
        seconds=time.monotonic() - started,
        peak_memory=peak,
        cut=cut,
        pid=pid or 0,
        standby=answer is not None,
    )


def query_isolated(
    store: Store,
    sql: str,
    params: Sequence[object],
    bounds: QueryBounds,
    sources: Sequence[str],
) -> pl.DataFrame:
    """`run_query(store, sql, params)` in a query process of its own, capped for its life
    within `bounds.limits` (a server's query holding a metric file's SQL: `query_limits(...,
    isolated=True)`), sharing the server's process slots with the SQL page. Errors as
    `run_query`'s, naming `sources`."""
    limits = bounds.limits
    subject = subject_of(store.out, sources)
    held = dict(store.sources) if store.in_memory else None  # Arrow tables: handed over
    args = (_Tables(store.out, held), sql, list(params), limits, tuple(sources))
    slots = _slot(bounds.max_queries or default_max_queries(limits), f"{', '.join(sources)}: ")
    try:
        _, data = _run_child(_query_child, args, limits, subject)
    finally:
        slots.release()
    return _frame(data)


def _frame(data: bytes) -> pl.DataFrame:
    return pl.from_arrow(pa.ipc.open_stream(data).read_all())


def _start(
    target: Callable[..., None], args: tuple, *, duplex: bool = False
) -> tuple[BaseProcess, Connection]:
    """A child forked from the forkserver running `target(conn, *args)`, and the parent's end
    of its pipe (`duplex`: both ways, for a standby that waits for its query)."""
    _CONTEXT.set_forkserver_preload(_PRELOAD)
    receiver, sender = _CONTEXT.Pipe(duplex=duplex)
    child = _CONTEXT.Process(target=target, args=(sender, *args), daemon=True)
    with _main_left_out():
        child.start()
    sender.close()
    return child, receiver


_MAIN = threading.Lock()


@contextmanager
def _main_left_out() -> Iterator[None]:
    """The main module left out of what a child is told while it starts: multiprocessing
    would have the child run the parent's script again first (as `__mp_main__`), and a
    user's script that calls the library without `if __name__ == "__main__":` (a count of
    `va.error_distribution`) would run twice and fail there. A child runs this package's
    functions only, found by their modules' names."""
    main = sys.modules["__main__"]
    with _MAIN:
        spec, names = getattr(main, "__spec__", None), vars(main)
        path = names.pop("__file__", None)
        main.__spec__ = None
        try:
            yield
        finally:
            main.__spec__ = spec
            if path is not None:
                main.__file__ = path


def _run_child(
    target: Callable[..., None], args: tuple, limits: SqlLimits, subject: str
) -> tuple[tuple, bytes]:
    """Run `target(conn, *args)` in a forked child; its answer (`_answer`)."""
    child, receiver = _start(target, args)
    return _answer(child, receiver, limits, subject)


def _answer(
    child: BaseProcess,
    receiver: Connection,
    limits: SqlLimits,
    subject: str,
) -> tuple[tuple, bytes]:
    """A query child's answer: the header `("ok", ...)` and the result's bytes. An error it
    answers is raised; past the time limit and a grace period it is killed, and a child that
    ends without an answer is reported (`subject` names the query). The child has ended when
    this returns."""
    wait = None if limits.timeout is None else limits.timeout + GRACE
    try:
        if not receiver.poll(wait):
            raise QueryLimitError(time_message(subject, limits), limit="time")
        header = receiver.recv()
        if header[0] == "error":
            _, kind, message, limit, _ = header
            raise _error(kind, message, limit)
        data = receiver.recv_bytes(maxlength=memory_headroom(limits))
    except (EOFError, OSError):
        child.join(timeout=GRACE)
        raise QueryLimitError(
            f"{subject} ended without an answer: its process exited with code "
            f"{child.exitcode}, most likely past its memory limit ({format_size(limits.memory)})",
            limit="memory",
        ) from None
    finally:
        receiver.close()
        if child.is_alive():
            child.kill()
        child.join()
    return header, data


__all__ = ["GRACE", "IsolatedResult", "query_isolated", "run_isolated", "warm_query_processes"]
