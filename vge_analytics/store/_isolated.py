"""One user query in a process of its own (the dashboard's SQL page).

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

At most `max_queries` children run at once across all the sessions of the server (each may
take its memory limit and half again): a query beyond them waits up to `SLOT_WAIT` seconds for
one to end, then is refused in one line.
"""

from __future__ import annotations

import multiprocessing
import resource
import threading
import time
from dataclasses import dataclass
from functools import cache
from multiprocessing.connection import Connection
from pathlib import Path

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
from ._sql import check_size, sql_head

GRACE = 5.0
"""Seconds the parent waits past the time limit before it kills the child (the child's own
timer normally ends the query first, with a clearer message)."""

_CONTEXT = multiprocessing.get_context("forkserver")
_ERRORS = {
    cls.__name__: cls for cls in (QueryError, QueryRefused, QueryLimitError, OutputDirError)
}


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


def warm_query_processes() -> None:
    """Start the forkserver now (it imports the libraries once), not on the first query."""
    _CONTEXT.set_forkserver_preload([__name__])
    from multiprocessing import forkserver

    forkserver.ensure_running()


@cache
def _slots(size: int) -> threading.BoundedSemaphore:
    """The process slots of this server for a cap of `size` (one cap per server in practice:
    `vge app --sql-max-queries`)."""
    return threading.BoundedSemaphore(size)


def _peak_memory() -> int:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def _child(conn: Connection, out: str, query: str, rows: int, limits: SqlLimits) -> None:
    """The query's process: run it within its limits, answer once, exit."""
    with conn, process_memory_cap(limits):
        try:
            head = sql_head(out, query, rows, limits=limits)
            frame, cut = bound_result(head.frame)
            table = frame.to_arrow()
            sink = pa.BufferOutputStream()
            with pa.ipc.new_stream(sink, table.schema) as writer:
                writer.write_table(table)
            conn.send(("ok", head.truncated, cut, _peak_memory()))
            conn.send_bytes(sink.getvalue())
        except AnalyticsError as exc:  # refused, failed, stopped, or OUT unreadable
            limit = getattr(exc, "limit", None)
            conn.send(("error", type(exc).__name__, str(exc), limit, _peak_memory()))
        except MemoryError:
            message = f"the query needed more memory than its limit ({limits.describe()})"
            conn.send(("error", "QueryLimitError", message, "memory", _peak_memory()))


def _error(kind: str, message: str, limit: str | None) -> Exception:
    cls = _ERRORS.get(kind, QueryError)
    if cls is QueryLimitError:
        return QueryLimitError(message, limit=limit or "memory")
    return cls(message)


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
    `default_max_queries(limits)`). Raises `QueryRefused`, `QueryLimitError` or `QueryError`
    (one line)."""
    check_size(query)  # too large: refused without a process; parsing is the child's job
    size = max_queries or default_max_queries(limits)
    slots = _slots(size)
    if not slots.acquire(timeout=SLOT_WAIT):
        raise QueryLimitError(
            f"{size} {'query is' if size == 1 else 'queries are'} running already, as many as "
            f"the SQL page runs at once; this one waited {SLOT_WAIT:g} s: run it again when "
            "one has ended",
            limit="queries",
        )
    try:
        return _run_child(out, query, rows, limits)
    finally:
        slots.release()


def _run_child(out: str | Path, query: str, rows: int, limits: SqlLimits) -> IsolatedResult:
    started = time.monotonic()
    _CONTEXT.set_forkserver_preload([__name__])
    receiver, sender = _CONTEXT.Pipe(duplex=False)
    child = _CONTEXT.Process(
        target=_child, args=(sender, str(out), query, rows, limits), daemon=True
    )
    child.start()
    sender.close()
    wait = None if limits.timeout is None else limits.timeout + GRACE
    try:
        if not receiver.poll(wait):
            raise QueryLimitError(
                f"the query ran past its time limit of {limits.timeout:g} s and was stopped",
                limit="time",
            )
        header = receiver.recv()
        if header[0] == "error":
            _, kind, message, limit, _ = header
            raise _error(kind, message, limit)
        _, truncated, cut, peak = header
        data = receiver.recv_bytes(maxlength=memory_headroom(limits))
    except (EOFError, OSError):
        child.join(timeout=GRACE)
        raise QueryLimitError(
            f"the query's process ended without an answer (exit code {child.exitcode}); "
            f"it most likely needed more than its memory limit ({format_size(limits.memory)})",
            limit="memory",
        ) from None
    finally:
        receiver.close()
        if child.is_alive():
            child.kill()
        child.join()
    frame = pl.from_arrow(pa.ipc.open_stream(data).read_all())
    return IsolatedResult(
        frame=frame,
        truncated=truncated,
        seconds=time.monotonic() - started,
        peak_memory=peak,
        cut=cut,
    )


__all__ = ["GRACE", "IsolatedResult", "run_isolated", "warm_query_processes"]
