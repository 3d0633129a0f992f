"""Resource limits of user SQL (`vge sql`, `vge_analytics.sql`, the dashboard's SQL page).

A query can ask for more than the machine has (a cross join of the steps table is hundreds
of millions of rows). Every place its memory can go is bounded:

- DuckDB's operators: `memory_limit` on the connection, with spilling to a private temporary
  directory capped by `max_temp_directory_size` (`SqlLimits.spill`);
- the result: streamed batch by batch (`vge sql --format csv|json`), or cut at a row cap (the
  dashboard, the formats for people), or collected only up to `SqlLimits.memory` bytes
  (`vge_analytics.sql`);
- what DuckDB does not account for (one value larger than memory, `repeat('x', 10^10)`): a
  cap on the process's data segment (`process_memory_cap`), taken by `vge sql` for the
  duration of the query and by the dashboard's query process for its whole life; under it
  a result is made a polars frame only when there is room left for it (`memory_room`,
  `_sql.polars_frame`: polars aborts where an allocation fails);
- time: the query is interrupted after `SqlLimits.timeout` seconds.
"""

from __future__ import annotations

import contextlib
import os
import re
import resource
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from .._errors import ConfigError

MEMORY_SHARE = 0.25
"""Default memory limit: this share of the machine's memory (or of the cgroup's limit)."""
SPILL_FACTOR = 2
"""Default spill limit: this many times the memory limit, on disk."""
CLI_TIMEOUT = 300.0
"""Default time limit of `vge sql` and `vge_analytics.sql` (seconds): far above any query
the dashboard runs (under a second on the full synthetic benchmark), short enough that a
query that never ends does not hold the machine."""
APP_TIMEOUT = 30.0
"""Default time limit of the dashboard's SQL page (seconds)."""
APP_MAX_ROWS = 10_000
"""Rows the dashboard's SQL page shows (and its CSV download holds)."""
CLI_MAX_ROWS = 10_000
"""Rows `vge sql` prints in the formats for people (table, markdown, latex)."""
MAX_SQL_TEXT = 1024**2
"""Bytes of SQL text a query may hold (1 MB), checked before anything parses it: DuckDB's
parser takes hundreds of times the text's size in memory, over a thousand for nested
parentheses (6.4 MB of them: 8 GB and 65 s), and no query needs a megabyte. A query under the
cap is parsed in its own process or within its memory limit (`process_memory_cap`)."""
MAX_METRIC_FILE = 256 * 1024
"""Bytes a metric file may hold (256 KB, a thousand times a real one), checked before it is
read whole: its expressions are parsed in the process that loads the folder (the dashboard's
server too): the costliest 256 KB found peaks at 0.7 GB for the whole process, 1 MB at 1.6
GB."""

SLOT_WAIT = 5.0
"""Seconds a query waits for a free process slot before it is refused."""

_UNITS = {"": 1, "B": 1, "K": 1024, "M": 1024**2, "G": 1024**3, "T": 1024**4}
_SIZE = re.compile(r"^\s*(\d+(?:\.\d+)?)\s*([KMGT]?)(?:I?B)?\s*$", re.IGNORECASE)


def parse_size(value: str | int) -> int:
    """Bytes from `268435456`, `256MB`, `256MiB`, `1.5GB`, `2G` (units are powers of 1024)."""
    if isinstance(value, int):
        size = value
    else:
        match = _SIZE.match(value)
        if match is None:
            raise ConfigError(f"not a memory size: {value!r} (examples: 512MB, 4GB)")
        size = int(float(match.group(1)) * _UNITS[match.group(2).upper()])
    if size < 16 * 1024**2:
        raise ConfigError(f"a memory limit below 16 MB is not usable, got {value!r}")
    return size


def format_size(size: int) -> str:
    """`268435456` -> `256 MB` (powers of 1024, as DuckDB and `parse_size` read them)."""
    for unit in ("TB", "GB", "MB", "KB"):
        scale = _UNITS[unit[0]]
        if size >= scale:
            value = size / scale
            return f"{value:.0f} {unit}" if value == int(value) else f"{value:.1f} {unit}"
    return f"{size} B"


def machine_memory() -> int:
    """Bytes of memory this process may use: the machine's, or its cgroup's limit if lower."""
    total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    with contextlib.suppress(OSError, ValueError):
        text = Path("/sys/fs/cgroup/memory.max").read_text().strip()
        if text != "max":
            total = min(total, int(text))
    return total


def default_memory_limit() -> int:
    return max(int(machine_memory() * MEMORY_SHARE), 64 * 1024**2)


@dataclass(frozen=True)
class SqlLimits:
    """How much one user query may take."""

    memory: int
    """Bytes DuckDB may hold in memory; also the most a collected result may take."""
    spill: int
    """Bytes DuckDB may write to its temporary directory when memory is full."""
    timeout: float | None
    """Seconds before the query is interrupted; None: no time limit."""

    @classmethod
    def make(
        cls, *, memory: str | int | None = None, timeout: float | None = CLI_TIMEOUT
    ) -> SqlLimits:
        """Limits from user options: `memory` as bytes or a size string (default: a quarter
        of the machine's memory), `timeout` in seconds (0 or None: none)."""
        size = default_memory_limit() if memory is None else parse_size(memory)
        if timeout is not None and timeout < 0:
            raise ConfigError(f"a time limit cannot be negative, got {timeout}")
        return cls(memory=size, spill=SPILL_FACTOR * size, timeout=timeout or None)

    def describe(self) -> str:
        return f"{format_size(self.memory)} in memory, {format_size(self.spill)} on disk"


def text_too_large(size: int, cap: int = MAX_SQL_TEXT) -> str | None:
    """Why `size` bytes of SQL text are refused past `cap` (None when they are not)."""
    if size <= cap:
        return None
    if size < 2 * cap:  # rounded, the two sizes could read the same
        return f"{size:,} bytes of text, more than the {format_size(cap)} ({cap:,} bytes) accepted"
    return f"{format_size(size)} of text, more than the {format_size(cap)} accepted"


def data_segment() -> int:
    """Bytes of the process's data segment now (VmData: what RLIMIT_DATA counts)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmData:"):
            return int(line.split()[1]) * 1024
    return 0  # pragma: no cover - every Linux kernel since 2.6 reports VmData


def memory_room() -> int | None:
    """Bytes the data segment may still grow by under its cap (`process_memory_cap`), at
    least 0; None when it is not capped."""
    soft, _ = resource.getrlimit(resource.RLIMIT_DATA)
    if soft == resource.RLIM_INFINITY:
        return None
    return max(0, soft - data_segment())


_POLARS_STARTED: set[int] = set()
"""The processes (ids) whose polars runtime `_start_polars` started (a forked child's is not)."""


def _start_polars() -> None:
    """Start polars' runtime (its thread pool, its allocator's first arena, its streaming
    engine's threads, the engine that writes CSV) and pyarrow's memory pool before a cap is
    set (some 1.1 GB of data segment where nothing started them, once per process:
    pyarrow's pool reserves 1 GB; the threads' stacks and arenas 6 MB each, 0.4 GB on 64
    cores): the cap is for what a query takes, and under it polars aborts the process where
    an allocation fails, or waits for ever for a thread it could not start."""
    if os.getpid() in _POLARS_STARTED:
        return
    import polars as pl

    pl.thread_pool_size()  # starts the pool
    pl.LazyFrame({"k": [0]}).group_by("k").len().collect(engine="streaming")  # (10 ms)
    # (not `pa.array` of Python values: that imports pandas)
    pl.from_arrow(pl.DataFrame({"s": ["started"]}).to_arrow()).write_csv()
    _POLARS_STARTED.add(os.getpid())


def memory_headroom(limits: SqlLimits) -> int:
    """What a query may add to the process beyond DuckDB's accounted memory: its result
    batches and DuckDB's unaccounted allocations (half the limit, at least 256 MB)."""
    return limits.memory + max(limits.memory // 2, 256 * 1024**2)


def default_max_queries(limits: SqlLimits) -> int:
    """How many query processes fit in this machine's memory, each at its bound (the memory
    limit and half again, `memory_headroom`); at least 1. With the default limit (a quarter of
    the machine) that is 2."""
    return max(1, machine_memory() // memory_headroom(limits))


@contextlib.contextmanager
def process_memory_cap(limits: SqlLimits) -> Iterator[None]:
    """Cap the process's data segment at its current size plus `memory_headroom(limits)`
    while the block runs (Linux; the soft limit only, restored afterwards).

    An allocation past the cap fails where it happens: DuckDB raises its out-of-memory
    error, Python raises MemoryError; neither grows the process further. Polars instead
    aborts the process: its runtime is started before the cap (`_start_polars`), and a query's
    result is made a polars frame only when there is room for it (`_sql.polars_frame`)."""
    _start_polars()
    try:
        soft, hard = resource.getrlimit(resource.RLIMIT_DATA)
        cap = data_segment() + memory_headroom(limits)
    except (OSError, ValueError):  # pragma: no cover - not Linux
        yield
        return
    if hard != resource.RLIM_INFINITY:
        cap = min(cap, hard)
    if soft != resource.RLIM_INFINITY:
        cap = min(cap, soft)
    resource.setrlimit(resource.RLIMIT_DATA, (cap, hard))
    # A panic in polars' threads under the cap (a Python object it could not make) would,
    # with RUST_BACKTRACE set, load the library's symbols to print a backtrace, fail to
    # allocate, and wait for ever on the lock the printer holds: without it, it raises.
    backtrace = os.environ.pop("RUST_BACKTRACE", None)
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_DATA, (soft, hard))
        if backtrace is not None:
            os.environ["RUST_BACKTRACE"] = backtrace


__all__ = [
    "APP_MAX_ROWS",
    "APP_TIMEOUT",
    "CLI_MAX_ROWS",
    "CLI_TIMEOUT",
    "MAX_METRIC_FILE",
    "MAX_SQL_TEXT",
    "SLOT_WAIT",
    "SqlLimits",
    "data_segment",
    "default_max_queries",
    "default_memory_limit",
    "format_size",
    "machine_memory",
    "memory_headroom",
    "memory_room",
    "parse_size",
    "process_memory_cap",
    "text_too_large",
]
