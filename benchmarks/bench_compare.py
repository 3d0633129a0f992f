"""Time of `vge compare` (one pair, clustered) and `vge compare --all` beside the compare of
c7fd47c (before clustering), and the clustered SE checked against statsmodels on the full
synthetic benchmark (not a test; numbers in docs/PERFORMANCE.md and docs/STATISTICS.md).

Usage (on the replayed full synthetic benchmark):

    vge synth --out /tmp/vge-full --scale full
    vge replay /tmp/vge-full/runs/* --bench /tmp/vge-full/bench --out /tmp/vge-full-out
    .venv/bin/python benchmarks/bench_compare.py /tmp/vge-full-out [--repeats 5] [--json]

Each round times, one after the other (the machine is shared: ratios hold where absolute
times do not), with the default resamples (2000):

- `baseline`: c7fd47c's `compare` (episodes resampled; its source read from git), sim-vlm-e
  against sim-vlm-f;
- `compare`: today's `compare` of the same pair (devices resampled, SEs, sign-flip test);
- `compare_episode`: the same with `cluster="episode"` (the baseline's intervals, bit for bit);
- `compare_all`: `compare_all` (every pair of the nine runs, SR);
- `cli_all`: `vge compare OUT --all -f json` as a process (with its start-up).

Medians and CPU seconds (all threads) are printed. Then the check: for three pairs, the
clustered SE of the paired SR difference against statsmodels' OLS of the per-episode
differences with cluster-robust covariance (groups = device); exit code 1 if any differs by
1e-9 or more.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import polars as pl
import statsmodels.api as sm

import vge_analytics as va

BASELINE_COMMIT = "c7fd47c"
PAIR = ("sim-vlm-e", "sim-vlm-f")
CHECKED = (("sim-vlm-e", "sim-vlm-f"), ("sim-human", "sim-vlm-f"), ("sim-vlm-f", "sim-vlm-f-hist0"))
ROOT = Path(__file__).resolve().parents[1]


def baseline_compare():
    """c7fd47c's `compare`, loaded as a module of `vge_analytics.reports` (its relative
    imports still resolve)."""
    source = subprocess.run(
        ["git", "show", f"{BASELINE_COMMIT}:vge_analytics/reports/_compare.py"],
        cwd=ROOT, capture_output=True, text=True, check=True,
    ).stdout  # fmt: skip
    name = "vge_analytics.reports._baseline_compare"
    spec = importlib.util.spec_from_loader(name, loader=None)
    module = importlib.util.module_from_spec(spec)
    module.__package__ = "vge_analytics.reports"
    sys.modules[name] = module  # dataclasses look their module up
    exec(compile(source, f"{BASELINE_COMMIT}:_compare.py", "exec"), module.__dict__)  # noqa: S102
    return module.compare


def _cpu() -> float:
    """CPU seconds of this process (all threads) and of its finished children (the CLI)."""
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + children.ru_utime + children.ru_stime


def _timed(fn) -> tuple[float, float]:
    c0, t0 = _cpu(), time.perf_counter()
    fn()
    return time.perf_counter() - t0, _cpu() - c0


def measure(out: Path, repeats: int) -> dict[str, dict[str, float]]:
    old = baseline_compare()
    cases = {
        "baseline": lambda: old(out, *PAIR),
        "compare": lambda: va.compare(out, *PAIR),
        "compare_episode": lambda: va.compare(out, *PAIR, cluster="episode"),
        "compare_all": lambda: va.compare_all(out),
        "cli_all": lambda: subprocess.run(
            [
                str(Path(sys.executable).with_name("vge")),
                "compare",
                str(out),
                "--all",
                "-f",
                "json",
            ],
            check=True,
            capture_output=True,
        ),  # fmt: skip
    }
    for fn in cases.values():  # warm: the store's views, the imports
        fn()
    times: dict[str, list[tuple[float, float]]] = {k: [] for k in cases}
    for _ in range(repeats):
        for name, fn in cases.items():
            times[name].append(_timed(fn))
    return {
        name: {
            "median_s": statistics.median(t for t, _ in runs),
            "best_s": min(t for t, _ in runs),
            "cpu_median_s": statistics.median(c for _, c in runs),
        }
        for name, runs in times.items()
    }


def check_against_statsmodels(out: Path) -> list[dict]:
    rows = []
    for a, b in CHECKED:
        se = va.compare(out, a, b, metrics="SR", resamples=1).metrics["se"][0]
        eps = va.episodes(
            out, where={"run_id": [a, b]}, columns=["run_id", "episode_id", "device_id", "success"]
        )
        left = eps.filter(pl.col("run_id") == a).select("episode_id", "device_id", "success")
        right = eps.filter(pl.col("run_id") == b).select("episode_id", pl.col("success").alias("b"))
        paired = left.join(right, on="episode_id").sort("episode_id")
        d = 100.0 * (paired["b"].cast(float) - paired["success"].cast(float)).to_numpy()
        groups = paired["device_id"].rank("dense").to_numpy()
        fit = sm.OLS(d, np.ones((len(d), 1))).fit(cov_type="cluster", cov_kwds={"groups": groups})
        rows.append({"pair": f"{a} vs {b}", "episodes": len(d), "ours": se, "statsmodels": float(fit.bse[0]), "difference": abs(se - float(fit.bse[0]))})  # fmt: skip
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path, help="replay output directory (full synthetic)")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    if not (args.out / "episodes").is_dir():
        print(f"error: {args.out}: not a replay output directory", file=sys.stderr)
        return 1
    times = measure(args.out, args.repeats)
    checked = check_against_statsmodels(args.out)
    load = os.getloadavg()[0]
    if args.json:
        print(json.dumps({"load_1min": load, "times": times, "statsmodels": checked}, indent=2))
    else:
        print(f"cpus {os.cpu_count()}, load average (1 min) {load:.2f}, {args.repeats} rounds")
        print("| case | median s | best s | cpu median s | x baseline |")
        print("|---|---:|---:|---:|---:|")
        base = times["baseline"]["median_s"]
        for name, t in times.items():
            print(f"| {name} | {t['median_s']:.2f} | {t['best_s']:.2f} | {t['cpu_median_s']:.2f} | {t['median_s'] / base:.2f} |")  # fmt: skip
        print("| pair | episodes | clustered SE | statsmodels | difference |")
        print("|---|---:|---:|---:|---:|")
        for r in checked:
            print(f"| {r['pair']} | {r['episodes']} | {r['ours']:.12f} | {r['statsmodels']:.12f} | {r['difference']:.1e} |")  # fmt: skip
    return 0 if all(r["difference"] < 1e-9 for r in checked) else 1


if __name__ == "__main__":
    sys.exit(main())
