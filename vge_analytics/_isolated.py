"""One user query in a process of its own (the dashboard's SQL page).

The dashboard serves every visitor from one process, so a query run inside it could take all
of it down: DuckDB's memory limit does not cover everything (one value larger than memory,
`repeat('x', 10^10)`), and a query that ignores its interrupt would hold a thread forever.
Here each query runs in a child process forked from a forkserver (it starts in milliseconds,
with the libraries already imported), with DuckDB's limits and its data segment capped
(`process_memory_cap`, for the child's whole life). The child sends back the first rows as
Arrow IPC, or the one-line error. The parent waits for the time limit plus a grace period
and kills a child that has not answered by then; a child that dies (killed, crashed) is
reported, and the next query gets a fresh child.
"""

from __future__ import annotations

import multiprocessing
import resource
import time
from dataclasses import dataclass
from multiprocessing.connection import Connection
from pathlib import Path

import polars as pl
import pyarrow as pa

from ._errors import QueryError, QueryLimitError, QueryRefused
from ._limits import SqlLimits, format_size, memory_headroom, process_memory_cap
from ._sql import check_read_only, sql_head

GRACE = 5.0
"""Seconds the parent waits past the time limit before it kills the child (the child's own
timer normally ends the query first, with a clearer message)."""

_CONTEXT = multiprocessing.get_context("forkserver")
_ERRORS = {cls.__name__: cls for cls in (QueryError, QueryRefused, QueryLimitError)}


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


def warm() -> None:
    """Start the forkserver now (it imports the libraries once), not on the first query."""
    _CONTEXT.set_forkserver_preload([__name__])
    from multiprocessing import forkserver

    forkserver.ensure_running()


def _peak_memory() -> int:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def _child(conn: Connection, out: str, query: str, rows: int, limits: SqlLimits) -> None:
    """The query's process: run it within its limits, answer once, exit."""
    with conn, process_memory_cap(limits):
        try:
            head = sql_head(out, query, rows, limits=limits)
            table = head.frame.to_arrow()
            sink = pa.BufferOutputStream()
            with pa.ipc.new_stream(sink, table.schema) as writer:
                writer.write_table(table)
            conn.send(("ok", head.truncated, _peak_memory()))
            conn.send_bytes(sink.getvalue())
        except (QueryError, QueryRefused) as exc:
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


def run_isolated(out: str | Path, query: str, rows: int, limits: SqlLimits) -> IsolatedResult:
    """The first `rows` rows of a read-only query over OUT, computed in a child process
    within `limits`. Raises `QueryRefused`, `QueryLimitError` or `QueryError` (one line)."""
    check_read_only(query)  # refused without starting a process
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
        _, truncated, peak = header
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
    )


__all__ = ["GRACE", "IsolatedResult", "run_isolated", "warm"]
