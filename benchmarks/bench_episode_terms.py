"""Keeping a metric's terms per episode (`store._episode_terms`), with parts of a given size.

    python benchmarks/bench_episode_terms.py OUT [--metric SR] [--episodes-per-query 500000]

Opens OUT within the bounds `vge metrics` sets (its default memory limit), removes the kept
terms per episode of OUT's cache folder, and computes and writes the metric's file as the
first `vge metrics OUT` does (for SR) or a metric's first interval (any metric), with
`EPISODES_PER_QUERY` set to the size given (a size above OUT's episodes: one query for all).
Prints the wall time, the CPU time of the process and its peak RSS (and the RSS with OUT
open). Run each size in a process of its own, alternating (docs/PERFORMANCE.md, *Terms per
episode written a part at a time*).
"""

from __future__ import annotations

import argparse
import os
import resource
import time
from pathlib import Path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--metric", default="SR")
    parser.add_argument("--episodes-per-query", type=int, default=500_000)
    args = parser.parse_args()

    import vge_analytics as va
    from replay.io import METRIC_CACHE_DIR
    from vge_analytics.store import _episode_terms, query_limits, sized_memory_limit

    _episode_terms.EPISODES_PER_QUERY = args.episodes_per_query
    with query_limits(memory=sized_memory_limit(str(args.out), None)):
        store = va.open_store(args.out)
        (ratio,) = va.MetricSet.builtin().resolve([args.metric])
        for kept in (args.out / METRIC_CACHE_DIR).glob("terms_*.parquet"):
            kept.unlink()
        opened = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        wall, cpu = time.perf_counter(), time.process_time()
        path = _episode_terms._keep(store, ratio, _episode_terms._held(store), ())
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    size = path.stat().st_size if path is not None else 0
    print(
        f"{args.metric}, {args.episodes_per_query:,} episodes a part: wall {wall:.1f} s, "
        f"CPU {cpu:.1f} s, peak RSS {peak / 1e6:.2f} GB (OUT open: {opened / 1e6:.2f} GB), "
        f"file {size / 1e6:.1f} MB, load {os.getloadavg()[0]:.1f}"
    )


if __name__ == "__main__":
    main()
