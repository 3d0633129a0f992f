"""How the analytics' queries are bounded within a block of code (`query_limits`).

Every query of the analytics (`run_query`: the metrics, a metric file's expressions, the
`--where` filters, the errors, comparisons, sweeps, rescoring, the dashboard's tables) runs
within the bounds the code around it set, the three `vge sql` takes (`_limits`):

- DuckDB's memory limit, with spilling up to twice that: the stores opened in the block
  (`open_store`, and the sweep's `memory_store`) take it;
- the time limit: the query is interrupted past it;
- a cap on what the process may add to its data segment for what DuckDB does not account
  for (`process_memory_cap`: one value larger than memory, `repeat(episode_id, 20000000)`).
  How depends on the process: a command (`capped`) caps its own process around each query,
  the allocation past it fails inside DuckDB and the command ends with one line; a server
  (`isolated`, the dashboard), whose threads serve every visitor and must not fail an
  allocation, runs each query that holds SQL a user wrote (a metric file's) in a process of
  its own, capped for its whole life (`_isolated`), and its own queries in its process.

Outside any block (the Python API's default) a query has DuckDB's default memory limit
(`SqlLimits.make()`) and no time limit, and the process is not capped.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from contextvars import ContextVar
from dataclasses import dataclass

from ._limits import SqlLimits


@dataclass(frozen=True)
class QueryBounds:
    """The bounds of the analytics' queries in a block (`query_limits`)."""

    limits: SqlLimits
    """DuckDB's memory and spill limits, the time limit; the process cap is sized from them
    (`memory_headroom`)."""
    capped: bool
    """Each query caps this process's data segment while it runs (a command's process)."""
    isolated: bool
    """Each query holding SQL a user wrote runs in a query process of its own, capped for
    its life; the others run here, not capped (a server's process)."""
    max_queries: int | None = None
    """With `isolated`: query processes at once in this process (None: as many as fit in the
    machine's memory, `default_max_queries`)."""


_BOUNDS: ContextVar[QueryBounds | None] = ContextVar("vge_analytics_query_bounds", default=None)


@contextlib.contextmanager
def _bounded(bounds: QueryBounds) -> Iterator[QueryBounds]:
    token = _BOUNDS.set(bounds)
    try:
        yield bounds
    finally:
        _BOUNDS.reset(token)


@contextlib.contextmanager
def query_limits(
    *,
    memory: str | int | None = None,
    timeout: float | None = None,
    isolated: bool = False,
    max_queries: int | None = None,
) -> Iterator[QueryBounds]:
    """Within the block, each query of the analytics runs within `memory` (bytes or `"4GB"`;
    default a quarter of the machine's memory: DuckDB's limit, and the process cap sized
    from it) and `timeout` seconds (None or 0: none); a query stopped by one raises
    `QueryLimitError` (one line, naming the metric files the query holds, else OUT).

    This process is capped around each query (`process_memory_cap`), unless `isolated`:
    then each query that holds a metric file's SQL runs in a process of its own (at most
    `max_queries` at once), and the others here, uncapped (a server, whose other threads
    must not fail an allocation). Per thread (a context variable)."""
    limits = SqlLimits.make(memory=memory, timeout=timeout)
    with _bounded(QueryBounds(limits, not isolated, isolated, max_queries)) as bounds:
        yield bounds


@contextlib.contextmanager
def query_time_limit(seconds: float | None) -> Iterator[None]:
    """Within the block, each query of the analytics is stopped after `seconds` (None or 0:
    no limit) with `QueryLimitError`; memory as outside a block (`query_limits` bounds it
    too). Per thread (a context variable)."""
    with _bounded(QueryBounds(SqlLimits.make(timeout=seconds), False, False)):
        yield


def within(limits: SqlLimits) -> contextlib.AbstractContextManager[QueryBounds]:
    """Within the block, each query of the analytics runs within `limits`, the process not
    capped around it (a query process, capped for its whole life already)."""
    return _bounded(QueryBounds(limits, False, False))


def query_bounds() -> QueryBounds | None:
    """The bounds of the analytics' queries here (`query_limits`); None outside a block."""
    return _BOUNDS.get()


def store_limits() -> SqlLimits:
    """The memory limits a store opened here takes: the block's, else the default."""
    bounds = _BOUNDS.get()
    return bounds.limits if bounds is not None else SqlLimits.make()


__all__ = [
    "QueryBounds",
    "query_bounds",
    "query_limits",
    "query_time_limit",
    "store_limits",
    "within",
]
