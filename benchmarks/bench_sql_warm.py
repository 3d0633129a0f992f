"""What a query process pays before its first query, and what the SQL page's standby saves.

    python benchmarks/bench_sql_warm.py OUT [--query NAME] [--ways none,episodes,count]

Each way runs in a new Python process, as a query child would (OUT opened afresh within the
SQL page's default limits, pyarrow's dataset module imported first, as the forkserver has
it): OUT is opened, then warmed one way, then the SQL page's example query `--query` runs
twice; each step's wall and CPU seconds and the process's resident memory after it. Ways:

- `none`: nothing ahead (a new child before the standby);
- a table name (`episodes`, `goals`, `steps`): the footers of its files read ahead, as the
  standby does for `store._standby.FOOTER_TABLES` (`read_footers`);
- `count`: `SELECT count(*) FROM episodes` ahead (a scan that reads the footers, and counts).

Results go to stdout as markdown (docs/PERFORMANCE.md, section "SQL").
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

QUERY = "Success rate and steps per model"


def _rss() -> int:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) * 1024
    return 0


def _step(call) -> dict:
    wall, cpu = time.perf_counter(), time.process_time()
    call()
    return {"wall": time.perf_counter() - wall, "cpu": time.process_time() - cpu, "rss": _rss()}


class _NoQuery:
    """The standby's pipe, no query coming."""

    def poll(self) -> bool:
        return False


def one_way(out: str, way: str, query: str) -> dict:
    """The steps of one way, in this process."""
    import pyarrow.dataset  # noqa: F401  (the forkserver has it imported)

    from vge_analytics.dashboard import EXAMPLE_QUERIES
    from vge_analytics.store import APP_TIMEOUT, SqlLimits, open_store, read_footers, sql_head

    limits = SqlLimits.make(timeout=APP_TIMEOUT)
    text = EXAMPLE_QUERIES[query]
    steps = {"open": _step(lambda: open_store(out, limits))}
    store = open_store(out, limits)
    if way == "count":
        steps["ahead"] = _step(lambda: sql_head(out, "SELECT count(*) FROM episodes", 1, limits=limits))
    elif way != "none":
        steps["ahead"] = _step(lambda: read_footers(store, (way,), _NoQuery(), limits))
    steps["query 1"] = _step(lambda: sql_head(out, text, 10_000, limits=limits))
    steps["query 2"] = _step(lambda: sql_head(out, text, 10_000, limits=limits))
    return steps


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--query", default=QUERY)
    parser.add_argument("--ways", default="none,episodes,count")
    parser.add_argument("--one", help=argparse.SUPPRESS)  # a way, in this process
    args = parser.parse_args()
    if args.one:
        print(json.dumps(one_way(str(args.out), args.one, args.query)))
        return
    print(f"OUT: {args.out}; query: {args.query}\n")
    print("| ahead | open: wall / CPU (s) | ahead: wall / CPU (s) | query 1: wall / CPU (s) "
          "| query 2: wall / CPU (s) | resident after ahead (MB) |")
    print("|---|---:|---:|---:|---:|---:|")
    for way in args.ways.split(","):
        cmd = [sys.executable, __file__, str(args.out), "--one", way, "--query", args.query]
        steps = json.loads(subprocess.run(cmd, check=True, capture_output=True).stdout)
        cells = [
            f"{steps[s]['wall']:.2f} / {steps[s]['cpu']:.2f}" if s in steps else "–"
            for s in ("open", "ahead", "query 1", "query 2")
        ]
        after = steps.get("ahead", steps["open"])["rss"] / 1024**2
        print(f"| {way} | {' | '.join(cells)} | {after:,.0f} |", flush=True)


if __name__ == "__main__":
    main()
