"""Time of the whole analytics suite, reading the replay Parquet directly (not a test).

Usage (on the replayed full synthetic benchmark):

    vge synth --out /tmp/vge-full --scale full
    vge replay /tmp/vge-full/runs/* --bench /tmp/vge-full/bench --out /tmp/vge-full-out
    .venv/bin/python benchmarks/bench_metrics.py /tmp/vge-full-out [--times 10] [--repeats 7]

The suite is what `vge metrics` + `vge errors` compute: all twelve PROTOCOL §6 metrics per run
(grouped by run_id, model), the error-type distribution per run (and the error groups derived
from it) and the switch classes per run. It is timed

- cold: the first call on a directory (opening the views, reading Parquet footers), and
- warm: later calls (the cached connection of `open_store`), median and best of `--repeats`,
  with the CPU seconds of all threads (stable under load from other processes),

at 1x and at `--times` x: OUT copied `times` times into `benchmarks/_work/metrics_x<N>/`
(or `--work`) with distinct run ids (`<run_id>~<k>`) and a manifest listing the copies, i.e.
`times` times the steps, episodes, goals and runs, each copy a real Parquet file (no
symlinks), so the queries read `times` times the bytes and produce `times` times the groups.
The metrics read the metric cache (`OUT/.metric-cache/`, written by the cold call); the
metrics from the tables alone (`cache=False`) and the polars implementation are timed once
each, warm, for reference. Prints a table and, with `--json`, the numbers as JSON.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import sys
import time
from pathlib import Path

import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

import vge_analytics as va
from replay.io import (
    PARTITIONED,
    RUNS_TABLE,
    STEPS_TABLE,
    listed_part,
    manifest_path,
    partition,
)
from vge_analytics.reports import groups_of

WORK = Path(__file__).resolve().parent / "_work"
BY = ("run_id", "model")


def suite(out: Path) -> dict[str, float]:
    """Run the suite once; wall seconds per part, and CPU seconds (all threads) in total."""
    c0 = time.process_time()
    t0 = time.perf_counter()
    va.metrics(out, by=BY)
    t1 = time.perf_counter()
    types = va.error_distribution(out, by=BY)
    groups_of(types, BY)
    t2 = time.perf_counter()
    va.switch_classes(out, by=BY)
    t3 = time.perf_counter()
    cpu = time.process_time() - c0
    return {
        "metrics": t1 - t0,
        "errors": t2 - t1,
        "switch_classes": t3 - t2,
        "total": t3 - t0,
        "cpu": cpu,
    }


def measure(out: Path, repeats: int) -> dict:
    va.clear_cache()
    t = time.perf_counter()
    va.open_store(out)
    opened = time.perf_counter() - t
    cold = suite(out)
    warm = [suite(out) for _ in range(repeats)]
    t = time.perf_counter()
    va.metrics(out, by=BY, cache=False)  # the tables alone (no metric cache)
    uncached_s = time.perf_counter() - t
    t = time.perf_counter()
    va.polars_metrics(out, by=BY)
    polars_s = time.perf_counter() - t
    rows = va.sql(out, "SELECT (SELECT count(*) FROM steps) AS steps, "
                  "(SELECT count(*) FROM episodes) AS episodes, "
                  "(SELECT count(*) FROM runs) AS runs").row(0, named=True)  # fmt: skip
    return {
        "out": str(out),
        **rows,
        "open_s": opened,
        "cold_total_s": cold["total"],
        "warm_median_s": statistics.median(w["total"] for w in warm),
        "warm_best_s": min(w["total"] for w in warm),
        "warm_cpu_median_s": statistics.median(w["cpu"] for w in warm),
        "warm_median_parts_s": {
            k: statistics.median(w[k] for w in warm)
            for k in ("metrics", "errors", "switch_classes")
        },
        "metrics_uncached_s": uncached_s,
        "polars_metrics_s": polars_s,
    }


def _copy_table(src: Path, dst: Path, times: int, partitioned: bool) -> None:
    for path in sorted(src.rglob("*.parquet")):
        table = pq.read_table(path)
        for k in range(times):
            run_ids = pc.binary_join_element_wise(
                table["run_id"], pa.scalar(f"~{k}"), pa.scalar("")
            )
            copy = table.set_column(table.schema.get_field_index("run_id"), "run_id", run_ids)
            if partitioned:
                run = copy["run_id"][0].as_py()
                target = dst / partition(run) / path.name
            else:
                target = dst / f"{path.stem}~{k}.parquet"
            target.parent.mkdir(parents=True, exist_ok=True)
            pq.write_table(copy, target)


def _copied_manifest(out: Path, times: int) -> dict:
    """OUT's manifest with each run repeated `times` times under its new id, listing the
    copies' files (what a replay of that many runs writes; a real lab's manifest is as large:
    every run lists the digests of its inputs)."""
    manifest = json.loads(manifest_path(out).read_bytes())
    runs = []
    for k in range(times):
        for entry in manifest["runs"]:
            run_id = f"{entry['run_id']}~{k}"
            outputs = {
                table: [
                    listed_part(table, run_id, name.rsplit("/", 1)[-1])
                    for name in entry["outputs"][table]
                ]
                for table in PARTITIONED
            }
            runs.append({**entry, "run_id": run_id, "outputs": {**entry["outputs"], **outputs}})
    totals = {k: v * times for k, v in manifest["totals"].items()}
    return {**manifest, "totals": totals, "runs": runs}


def build_copies(out: Path, times: int, work: Path = WORK) -> Path:
    """OUT repeated `times` times under new run ids, with its manifest (rebuilt when OUT's
    manifest changed)."""
    dst = work / f"metrics_x{times}"
    stamp = dst / "source.json"
    source = {"out": str(out.resolve()), "manifest_mtime": manifest_path(out).stat().st_mtime}
    if stamp.exists() and json.loads(stamp.read_text()) == source:
        return dst
    shutil.rmtree(dst, ignore_errors=True)
    for table in PARTITIONED:
        _copy_table(out / table, dst / table, times, partitioned=True)
    _copy_table(out / RUNS_TABLE, dst / RUNS_TABLE, times, partitioned=False)
    manifest_path(dst).write_text(json.dumps(_copied_manifest(out, times), indent=2) + "\n")
    stamp.write_text(json.dumps(source))
    return dst


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path, help="replay output directory (full synthetic)")
    parser.add_argument("--times", type=int, default=10, help="repetition factor (10)")
    parser.add_argument("--repeats", type=int, default=7, help="warm repeats (7)")
    parser.add_argument("--json", action="store_true", help="print the numbers as JSON")
    parser.add_argument(
        "--work", type=Path, default=WORK, help=f"where the copies are made ({WORK})"
    )
    args = parser.parse_args(argv)
    if not (args.out / STEPS_TABLE).is_dir():
        print(f"error: {args.out}: not a replay output directory", file=sys.stderr)
        return 1
    results = [measure(args.out, args.repeats)]
    t = time.perf_counter()
    big = build_copies(args.out, args.times, args.work)
    print(f"({args.times}x copy ready in {time.perf_counter() - t:.1f} s: {big})", file=sys.stderr)
    results.append(measure(big, args.repeats))
    load = os.getloadavg()[0]  # after the runs: the load they ran under (incl. themselves)
    if args.json:
        print(json.dumps({"load_1min": load, "results": results}, indent=2))
        return 0
    print(f"cpus {os.cpu_count()}, load average (1 min) {load:.2f}")
    header = ("scale", "steps", "episodes", "runs", "open", "cold", "warm med", "warm best",
              "warm cpu", "metrics uncached", "polars")  # fmt: skip
    print(" | ".join(header))
    for scale, r in zip(("1x", f"{args.times}x"), results, strict=True):
        print(
            " | ".join(
                [
                    scale,
                    f"{r['steps']:,}",
                    f"{r['episodes']:,}",
                    str(r["runs"]),
                    f"{r['open_s']:.3f}",
                    f"{r['cold_total_s']:.3f}",
                    f"{r['warm_median_s']:.3f}",
                    f"{r['warm_best_s']:.3f}",
                    f"{r['warm_cpu_median_s']:.3f}",
                    f"{r['metrics_uncached_s']:.3f}",
                    f"{r['polars_metrics_s']:.3f}",
                ]
            )
        )
        parts = r["warm_median_parts_s"]
        print("   warm median parts: " + ", ".join(f"{k} {v:.3f}" for k, v in parts.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
