"""Calibration of `vge compare`'s intervals and tests on synthetic pairs whose truth is known
(not a test; numbers in docs/STATISTICS.md).

Usage:

    .venv/bin/python benchmarks/bench_calibration.py [--benchmarks 100] [--spreads 0,1]
        [--workers 1] [--resamples 2000] [--json]

Each replicate r is a fresh synthetic benchmark (`vge synth --scale sample --seed r`: 52 new
devices, 312 new episodes) with two seeds of two profiles (`--seeds 2 --runs
sim-vlm-e,sim-vlm-f`, and `--device-spread S`), replayed. On it:

- two pairs with no true difference: two seeds of one profile (sim-vlm-f and
  sim-vlm-f-seed1; sim-vlm-e and sim-vlm-e-seed1), the same agent on the same episodes;
- two pairs with a true shift: sim-vlm-e against sim-vlm-f, and their seeds 1 likewise. The
  truth is the expected SR difference over benchmarks and agents, estimated for replicate r
  by the mean of the other replicates' differences (leave one out, so it does not share r's
  noise).

So 100 benchmarks give 200 pairs of each kind (the two pairs of a benchmark share its
devices: they are not independent of each other, the benchmarks are).

Each pair is compared with `--cluster device` and `--cluster episode` (SR, the default
resamples and test). Reported per spread and cluster: the false-positive rate at alpha 0.05
of the sign-flip p-value, of "the 95% interval excludes 0", of McNemar's exact test and of
the clustered McNemar test on the null pairs; the coverage of the 95% interval (null pairs:
of 0; shift pairs: of the truth); the mean design effect and interval width. With R pairs a
rate's standard error is about sqrt(0.05 * 0.95 / R) (0.015 for R = 200).

Results go to `benchmarks/_work/calibration/spread-<S>.jsonl`, one line per replicate, as
they finish: an interrupted run resumes where it stopped.
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import statistics
import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import replay
import vge_analytics as va
from vge_analytics.synth import generate

WORK = Path(__file__).resolve().parent / "_work" / "calibration"
NULL_PAIRS = (("sim-vlm-f", "sim-vlm-f-seed1"), ("sim-vlm-e", "sim-vlm-e-seed1"))
SHIFT_PAIRS = (("sim-vlm-e", "sim-vlm-f"), ("sim-vlm-e-seed1", "sim-vlm-f-seed1"))
CLUSTERS = ("device", "episode")
ALPHA = 0.05


def replicate(r: int, spread: float, resamples: int) -> dict:
    """One fresh benchmark, its runs replayed, every pair compared both ways."""
    root = Path(tempfile.mkdtemp(prefix=f"calibration-{r}-", dir=WORK))
    try:
        generate(
            root / "synth",
            scale="sample",
            seed=r,
            workers=1,
            agent_seeds=2,
            only_runs=["sim-vlm-e", "sim-vlm-f"],
            device_spread=spread,
        )
        runs = sorted(p for p in (root / "synth" / "runs").iterdir() if p.is_dir())
        replay.replay_runs(runs, root / "synth" / "bench", root / "out", progress=False, workers=1)
        result: dict = {"replicate": r, "spread": spread}
        for cluster in CLUSTERS:
            for kind, pairs in (("null", NULL_PAIRS), ("shift", SHIFT_PAIRS)):
                for a, b in pairs:
                    c = va.compare(
                        root / "out", a, b, metrics="SR", cluster=cluster, resamples=resamples
                    )
                    sr = c.metrics.row(0, named=True)
                    m = c.mcnemar.row(0, named=True)
                    result[f"{cluster}:{kind}:{a}:{b}"] = {
                        k: sr[k] for k in ("diff", "ci_low", "ci_high", "se", "deff", "p_value")
                    } | {"mcnemar": m["p_value"], "p_cluster": m["p_cluster"]}
        va.clear_cache()
        return result
    finally:
        shutil.rmtree(root, ignore_errors=True)


def _done(path: Path) -> dict[int, dict]:
    if not path.exists():
        return {}
    rows = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
    return {row["replicate"]: row for row in rows}


def run(spread: float, benchmarks: int, workers: int, resamples: int) -> list[dict]:
    path = WORK / f"spread-{spread:g}.jsonl"
    done = _done(path)
    todo = [r for r in range(benchmarks) if r not in done]
    with path.open("a") as out, ProcessPoolExecutor(max_workers=workers) as pool:
        futures = [pool.submit(replicate, r, spread, resamples) for r in todo]
        for future in futures:
            row = future.result()
            out.write(json.dumps(row) + "\n")
            out.flush()
            done[row["replicate"]] = row
            print(f"spread {spread:g}: {len(done)}/{benchmarks}", flush=True)
    return [done[r] for r in range(benchmarks)]


def _rate(flags: list[bool]) -> float:
    return sum(flags) / len(flags)


def summarise(rows: list[dict], spread: float) -> list[dict]:
    """One line per cluster: false positives, coverage, design effect, width."""
    out = []
    # each replicate's mean shift, and the truth left out of each: the others' mean
    means = [
        statistics.mean(row[f"device:shift:{a}:{b}"]["diff"] for a, b in SHIFT_PAIRS)
        for row in rows
    ]
    total = sum(means)
    truths = [(total - m) / (len(means) - 1) for m in means]
    for cluster in CLUSTERS:
        nulls = [row[f"{cluster}:null:{a}:{b}"] for row in rows for a, b in NULL_PAIRS]
        shifts = [
            (row[f"{cluster}:shift:{a}:{b}"], t)
            for row, t in zip(rows, truths, strict=True)
            for a, b in SHIFT_PAIRS
        ]
        out.append(
            {
                "spread": spread,
                "cluster": cluster,
                "null_pairs": len(nulls),
                "fpr_sign_flip": _rate([n["p_value"] < ALPHA for n in nulls]),
                "fpr_interval": _rate([n["ci_low"] > 0 or n["ci_high"] < 0 for n in nulls]),
                "fpr_mcnemar": _rate([n["mcnemar"] < ALPHA for n in nulls]),
                "fpr_clustered_mcnemar": _rate([n["p_cluster"] < ALPHA for n in nulls]),
                "coverage_null": _rate([n["ci_low"] <= 0 <= n["ci_high"] for n in nulls]),
                "shift_pairs": len(shifts),
                "truth": total / len(means),
                "coverage_shift": _rate([s["ci_low"] <= t <= s["ci_high"] for s, t in shifts]),
                "deff_null": statistics.mean(n["deff"] for n in nulls),
                "deff_shift": statistics.mean(s["deff"] for s, _ in shifts),
                "width_shift": statistics.mean(s["ci_high"] - s["ci_low"] for s, _ in shifts),
                "power_shift": _rate([s["p_value"] < ALPHA for s, _ in shifts]),
            }
        )
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--benchmarks", type=int, default=100, help="replicates (2 pairs each)")
    parser.add_argument("--spreads", default="0,1", help="--device-spread values")
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--resamples", type=int, default=2000)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    WORK.mkdir(parents=True, exist_ok=True)
    lines = []
    for spread in (float(s) for s in args.spreads.split(",")):
        rows = run(spread, args.benchmarks, args.workers, args.resamples)
        lines.extend(summarise(rows, spread))
    if args.json:
        print(json.dumps(lines, indent=2))
        return
    keys = list(lines[0])
    print("| " + " | ".join(keys) + " |")
    print("|" + "---|" * len(keys))
    for line in lines:
        cells = [
            f"{v:.3f}" if isinstance(v, float) and not math.isnan(v) else str(v)
            for v in line.values()
        ]
        print("| " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
