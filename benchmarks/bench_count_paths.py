"""The first step counts of OUT by one path: polars in its process, or DuckDB's query.

    python benchmarks/bench_count_paths.py OUT polars|duckdb

Removes the step counts kept beside OUT (`OUT/.metric-cache/counts_*`), sets
`store._scan_counts.POLARS_FROM_BYTES` so that the chosen path counts whatever OUT's size,
then times the first error shares, switch classes and clicked views (`va.error_distribution`,
`va.switch_classes`, `dashboard.interaction_views`), in this process: wall seconds, and CPU
seconds of this process plus the count's process (polars). The first call includes opening
OUT and, for polars, starting the forkserver, as a command's first count does. Run each path
in a fresh process, alternating (docs/PERFORMANCE.md, *The first count's memory bound*).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("path", choices=("polars", "duckdb"))
    args = parser.parse_args()
    for kept in (args.out / ".metric-cache").glob("counts_*"):
        kept.unlink()
    import vge_analytics as va
    from vge_analytics import dashboard
    from vge_analytics.store import _scan_counts

    _scan_counts.POLARS_FROM_BYTES = 0 if args.path == "polars" else 1 << 62
    calls = (
        ("error shares", va.error_distribution),
        ("switch classes", va.switch_classes),
        ("clicked views", dashboard.interaction_views),
    )
    for name, call in calls:
        _scan_counts.last_process = None
        started, cpu = time.perf_counter(), time.process_time()
        call(args.out)
        wall, cpu = time.perf_counter() - started, time.process_time() - cpu
        child = _scan_counts.last_process
        cpu += child.cpu_seconds if child is not None else 0.0
        print(f"{args.path:6s} {name:14s} wall {wall:6.2f} s  cpu {cpu:6.2f} s", flush=True)


if __name__ == "__main__":
    main()
