"""A first dashboard server's data calls, in one process: each page's first choice, then others.

    python benchmarks/bench_first_server.py OUT [--cold | --after-metrics] [--counts]
        [--counts-of EARLIER]

Calls, in order and timed once each, what the Leaderboard, Errors, Navigation and Grounding
pages ask for on a first server (`va.metric_intervals`, `va.error_distribution`,
`va.switch_classes`, `dashboard.interaction_views`): the page's default, then another
grouping or a category filter, as a visitor choosing them would. The dashboard's kept results
(`result-*`) are not used (the functions are called directly), so this times what a first
server computes; `--cold` first removes the terms per episode and the step counts kept in
`OUT/.metric-cache/` (`terms_*`, `counts_*`: docs/METRICS.md), so that the first calls
compute them. `--after-metrics` does that, then runs the first `vge metrics OUT -f json` (its
per-run terms and kept answers removed too, the tables' schemas kept; timed, in a process of
its own, with this Python and PYTHONPATH), and times the Leaderboard's other calls of a
first visit first (the run list, the filters' values, completeness, the metrics, the costs),
as a first server after `vge metrics` makes them. The CPU seconds are this process's, all its
threads (on a shared machine they vary less than the wall time), plus those of a step count's
own process (`store._scan_counts`: its peak memory printed on stderr). `--counts` times only the
Errors, Navigation and Grounding calls (the step counts: their first count, then another
choice each). `--counts-of EARLIER` first puts the step counts kept in the cache folder of
EARLIER (`counts_*`: another OUT, say OUT with one run fewer, counted once) in OUT's, in
place of its own, as an earlier content of OUT would have left them: the first counts are
then those of a first server after a run was replayed into OUT (or removed from it). Run it
for BASE with `PYTHONPATH=BASE` beside this tree, alternating (docs/PERFORMANCE.md, *The
first server at 100x*).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--cold", action="store_true", help="forget the kept terms and counts")
    parser.add_argument(
        "--after-metrics", action="store_true", help="--cold, then the first `vge metrics OUT`"
    )
    parser.add_argument("--counts", action="store_true", help="only the step counts' calls")
    parser.add_argument(
        "--counts-of", type=Path, help="the step counts kept of this OUT put in OUT's first"
    )
    args = parser.parse_args()
    out: Path = args.out
    if args.cold or args.after_metrics:
        forget(out, args.after_metrics)
    if args.counts_of is not None:
        counts_of(args.counts_of, out)
    if args.after_metrics:
        started = time.perf_counter()
        command = [sys.executable, "-m", "vge_analytics.cli", "metrics", str(out), "-f", "json"]
        subprocess.run(command, check=True, stdout=subprocess.DEVNULL)
        print(f"first `vge metrics OUT`: {time.perf_counter() - started:.2f} s")

    import vge_analytics as va
    from vge_analytics import dashboard as dash

    run = ["run_id", "model"]
    category = {"category": ["Microwave"]}
    calls = leaderboard_calls(out) if args.after_metrics else []
    calls += [
        ("intervals of SR by run", lambda: va.metric_intervals(out, by=run, where={})),
        ("intervals of SR by model", lambda: va.metric_intervals(out, by=["model"], where={})),
        (
            "intervals of SR by run, category filtered",
            lambda: va.metric_intervals(out, by=run, where=category),
        ),
        (
            "intervals of SPL by run",
            lambda: va.metric_intervals(out, metric="SPL", by=run, where={}),
        ),
        ("error shares by run", lambda: va.error_distribution(out, by=run, labels=True)),
        (
            "error shares by model, category filtered",
            lambda: va.error_distribution(out, by=["model"], where=category, labels=True),
        ),
        ("switch classes by run", lambda: va.switch_classes(out, by=run, where={})),
        ("switch classes by category", lambda: va.switch_classes(out, by=["category"])),
        ("clicked views", lambda: dash.interaction_views(out, where={})),
        ("clicked views, category filtered", lambda: dash.interaction_views(out, where=category)),
    ]
    if args.counts:  # the intervals left out
        calls = [(name, call) for name, call in calls if not name.startswith("intervals")]
    if not args.after_metrics:  # (with it, the Leaderboard's first call opens OUT)
        va.runs(out)  # OUT opened, as a server has it before a page asks
    print("| call, in order | seconds | CPU seconds |\n|---|---:|---:|")
    for name, call in calls:
        started, cpu = time.perf_counter(), time.process_time()
        call()
        wall, cpu = time.perf_counter() - started, time.process_time() - cpu
        print(f"| {name} | {wall:.2f} | {cpu + count_process():.2f} |", flush=True)


def count_process() -> float:
    """The CPU seconds of the step count's own process in the last call (0: none), forgotten
    (a tree where the first count runs in a process of its own: `store._scan_counts`); its
    peak resident memory printed."""
    from vge_analytics.store import _scan_counts

    ran, _scan_counts.last_process = getattr(_scan_counts, "last_process", None), None
    if ran is None:
        return 0.0
    print(f"  (the count's process: {ran.peak_memory / 1e9:.2f} GB peak)", file=sys.stderr)
    return ran.cpu_seconds


def forget(out: Path, answers: bool) -> None:
    """Remove the kept terms per episode and step counts; with `answers`, also the per-run
    terms and kept answers of `vge metrics`."""
    from replay.io import METRIC_CACHE_DIR

    patterns = ["terms_*.parquet", "counts_*.parquet"]
    if answers:
        patterns += ["episodes-*.parquet", "steps-*.parquet", "goals-*.parquet", "answer-*"]
    for pattern in patterns:
        for kept in (out / METRIC_CACHE_DIR).glob(pattern):
            kept.unlink()


def counts_of(earlier: Path, out: Path) -> None:
    """Put the step counts kept in EARLIER's cache folder in OUT's, in place of its own."""
    import shutil

    from replay.io import METRIC_CACHE_DIR

    for kept in (out / METRIC_CACHE_DIR).glob("counts_*.parquet"):
        kept.unlink()
    (out / METRIC_CACHE_DIR).mkdir(exist_ok=True)
    for kept in sorted((earlier / METRIC_CACHE_DIR).glob("counts_*.parquet")):
        shutil.copy2(kept, out / METRIC_CACHE_DIR / kept.name)


def leaderboard_calls(out: Path) -> list:
    """The Leaderboard's calls of a first visit before its intervals, with its defaults."""
    import vge_analytics as va
    from vge_analytics import dashboard as dash

    run = ["run_id", "model"]
    return [
        ("summary of OUT (opens it)", lambda: dash.out_summary(out)),
        ("run facets", lambda: dash.run_facets(out)),
        ("run list", lambda: va.runs(out)),
        ("categories", lambda: dash.column_values(out, "episodes", "category")),
        ("goal counts", lambda: dash.column_values(out, "episodes", "n_goals")),
        ("completeness", lambda: va.completeness(out)),
        ("metrics by run", lambda: va.metrics(out, by=run, where={})),
        ("costs by run", lambda: dash.cost_table(out, run, {})),
    ]


if __name__ == "__main__":
    main()
