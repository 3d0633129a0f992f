"""What the SQL limits cost: a query in its own process against one in the calling process,
and how fast `vge sql` streams a result that does not fit in memory.

    python benchmarks/bench_sql.py OUT [--repeat 7] [--stream-seconds 5] [--pause 1]

- *in process*: `vge_analytics.sql` (the Python API, DuckDB in this process), median of
  `--repeat`, after one warm-up;
- *own process*: `dashboard.sql_preview`, what the dashboard's SQL page runs: a child forked
  from the forkserver (started once, before timing), first 10,000 rows, median of `--repeat`;
- *standby*: the same with the SQL page's standby kept (`store._standby`, as `vge app` keeps
  it): each query runs in the standby forked after the one before, `--pause` seconds after
  it (untimed: a person reads a result before the next query), median of `--repeat`; the
  count of queries that ran in a standby is printed;
- *stream*: `vge sql OUT "select a.output, b.output from steps a, steps b" --format csv` as a
  real process for `--stream-seconds` (its time limit), output counted and thrown away:
  bytes and rows per second, and the process's peak resident memory against `SELECT 1`.

Results go to stdout as markdown (docs/PERFORMANCE.md, section "SQL").
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import subprocess
import sys
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

CROSS_JOIN = "select a.output, b.output from steps a, steps b"


def timed(call, repeat: int) -> float:
    call()
    times = []
    for _ in range(repeat):
        started = time.perf_counter()
        call()
        times.append(time.perf_counter() - started)
    return statistics.median(times)


def timed_standby(call, repeat: int, pause: float) -> tuple[float, int]:
    """Median seconds of `call()` each `pause` seconds after the one before, and how many of
    the timed calls ran in a standby."""
    call()
    times, used = [], 0
    for _ in range(repeat):
        time.sleep(pause)
        started = time.perf_counter()
        used += call().standby
        times.append(time.perf_counter() - started)
    return statistics.median(times), used


def stream(out: Path, query: str, seconds: float) -> tuple[int, int, int, float]:
    """(bytes written, lines, peak RSS bytes, wall seconds) of `vge sql ... --format csv`."""
    cmd = [sys.executable, "-m", "vge_analytics.cli", "sql", str(out), query, "--format", "csv"]
    cmd += ["--timeout", f"{seconds:g}"]
    started = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
    counted = {"bytes": 0, "lines": 0}

    def drain() -> None:
        assert proc.stdout is not None
        while chunk := proc.stdout.read1(1 << 20):
            counted["bytes"] += len(chunk)
            counted["lines"] += chunk.count(b"\n")

    reader = threading.Thread(target=drain)
    reader.start()
    _, _, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - started
    reader.join()
    return counted["bytes"], counted["lines"], usage.ru_maxrss * 1024, wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--repeat", type=int, default=7)
    parser.add_argument("--stream-seconds", type=float, default=5.0)
    parser.add_argument("--pause", type=float, default=1.0, help="seconds between standby queries")
    args = parser.parse_args()

    import vge_analytics as va
    from vge_analytics import dashboard as dash
    from vge_analytics.store import (
        APP_MAX_ROWS,
        APP_TIMEOUT,
        SqlLimits,
        keep_standby,
        stop_standbys,
        warm_query_processes,
    )

    out = dash.check_out(args.out)
    summary = dash.out_summary(out)
    limits = SqlLimits.make(timeout=APP_TIMEOUT)
    warm_query_processes()
    queries = {"SELECT 1": "SELECT 1 AS one", **dash.EXAMPLE_QUERIES}
    rows = []
    for name, query in queries.items():
        inside = timed(lambda q=query: va.sql(out, q), args.repeat)
        own = timed(lambda q=query: dash.sql_preview(out, q, APP_MAX_ROWS, limits), args.repeat)
        keep_standby(out, limits)
        kept, used = timed_standby(
            lambda q=query: dash.sql_preview(out, q, APP_MAX_ROWS, limits), args.repeat, args.pause
        )
        stop_standbys()
        rows.append((name, inside, own, kept, used))
        print(f"{name}: {inside:.3f} s / {own:.3f} s / {kept:.3f} s ({used})", file=sys.stderr)

    base_bytes, _, base_peak, base_wall = stream(out, "select 1 as one", args.stream_seconds)
    del base_bytes
    written, lines, peak, wall = stream(out, CROSS_JOIN, args.stream_seconds)

    print(
        f"OUT: {out} ({summary.runs} runs, {summary.episodes:,} episodes, {summary.steps:,} "
        f"steps); {platform.machine()}, {os.cpu_count()} CPUs, Python "
        f"{platform.python_version()}\n"
    )
    print(
        "| query | in process, median (s) | own process, median (s) | difference (s) "
        "| standby, median (s) | difference (s) | in the standby |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|")
    for name, inside, own, kept, used in rows:
        print(
            f"| {name} | {inside:.3f} | {own:.3f} | {own - inside:+.3f} | {kept:.3f} "
            f"| {kept - inside:+.3f} | {used} of {args.repeat} |"
        )
    streaming = wall - base_wall
    print(
        f'\n`vge sql OUT "{CROSS_JOIN}" --format csv --timeout {args.stream_seconds:g}`: '
        f"{written / 1024**2:,.0f} MB, {lines:,} lines in {wall:.1f} s "
        f"({written / 1024**2 / streaming:,.0f} MB/s after start-up); peak resident memory "
        f"{peak / 1024**2:.0f} MB against {base_peak / 1024**2:.0f} MB for `SELECT 1`"
    )


if __name__ == "__main__":
    main()
