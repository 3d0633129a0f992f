"""How long `vge` takes to start, as whole processes (not a test): the figures of
docs/PERFORMANCE.md, "Start-up".

    python benchmarks/bench_startup.py --base DIR [--runs 11] [--out OUT [--cold]] [--base-path DIR]

DIR is a checkout of the baseline commit with its kernel built in place (for example
`git worktree add DIR c7fd47c`, then `python setup.py build_ext --inplace` there). Each
command runs as `python -m vge_analytics.cli ...` with PYTHONPATH set to this checkout or
DIR (and run from there), the two alternating run by run (the machine is shared: ratios hold where absolute times
do not); each figure is the median wall time and the peak resident memory of the process
(`wait4`), and the median CPU time (user and system), which a busy machine changes less than
the wall time. The commands:

- `--help` and `metrics --help`: the help of the router and of a command;
- `metrics MISSING`: the fixed cost of a command that reads OUT, everything before its
  first file (interpreter, imports of the store, DuckDB, polars, pyarrow), then its one-line
  error: OUT does not exist;
- `metrics OUT` (with `--out`): the built-in suite over every run of OUT, as JSON, its metric
  cache warm (each tree runs it once first, unmeasured: the cache file's name depends on the
  metrics' definitions, the same in both trees unless they differ; a tree that keeps the
  answers of `vge metrics` prints the one kept then);
- `metrics OUT, table`: the same in the table format, as a person runs it (printed to a
  pipe here, so rich renders it 400 columns wide and without colours);
- `metrics OUT, cold` (with `--cold`): the JSON of the first `vge metrics` on a copy of OUT
  without its `.metric-cache` (made afresh before each run, untimed): what keeping the
  metric cache and the answer costs the first time;
- `libraries`: the libraries `vge metrics OUT` cannot do without imported, nothing else
  (DuckDB, polars, pyarrow.parquet, and typer), the floor
  of a command that reads OUT;
- `python -c pass`: the interpreter alone, the floor of every command.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from replay.io import METRIC_CACHE_DIR

ROOT = Path(__file__).resolve().parents[1]
MiB = 1 << 20


def run(tree: Path, args: list[str], first: Path | None = None) -> tuple[float, float, int, int]:
    """(wall seconds, CPU seconds, peak resident bytes, exit code) of one process run from
    `tree` (its folder the current one: `python -m` looks there first), with `first` before
    it on the module path if given."""
    path = str(tree) if first is None else f"{first}{os.pathsep}{tree}"
    env = {**os.environ, "PYTHONPATH": path}
    started = time.perf_counter()
    proc = subprocess.Popen(
        [sys.executable, *args],
        env=env,
        cwd=tree,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    _, status, usage = os.wait4(proc.pid, 0)
    seconds = time.perf_counter() - started
    proc.returncode = os.waitstatus_to_exitcode(status)
    return seconds, usage.ru_utime + usage.ru_stime, usage.ru_maxrss * 1024, proc.returncode


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--base", type=Path, required=True, help="checkout of the baseline")
    parser.add_argument("--runs", type=int, default=11, help="runs of each command and tree")
    parser.add_argument("--out", type=Path, help="a replay output: also time `vge metrics OUT`")
    parser.add_argument(
        "--base-path",
        type=Path,
        help="a folder put first on the baseline's module path, e.g. other versions of "
        "libraries (`pip install --target DIR typer==0.29.2 --no-deps`)",
    )
    parser.add_argument(
        "--cold", action="store_true", help="with --out: also time it on a copy without cache"
    )
    options = parser.parse_args()
    missing = Path(tempfile.mkdtemp(prefix="vge-startup-")) / "no-such-out"
    cases = {
        "vge --help": ["-m", "vge_analytics.cli", "--help"],
        "vge metrics --help": ["-m", "vge_analytics.cli", "metrics", "--help"],
        "vge metrics MISSING": ["-m", "vge_analytics.cli", "metrics", str(missing)],
    }
    trees = {"baseline": options.base.resolve(), "this tree": ROOT}
    firsts = {"baseline": options.base_path, "this tree": None}
    if options.out is not None:
        metrics = ["-m", "vge_analytics.cli", "metrics", str(options.out.resolve()), "-f", "json"]
        cases["vge metrics OUT"] = metrics
        cases["vge metrics OUT, table"] = metrics[:-2]
        for tree, path in trees.items():  # the metric cache filled, the schemas kept
            for args in (metrics, metrics[:-2]):
                run(path, args, firsts[tree])
    fresh = missing.parent / "cold-out"
    if options.out is not None and options.cold:
        cases["vge metrics OUT, cold"] = [*metrics[:3], str(fresh), "-f", "json"]
    cases["libraries"] = ["-c", "import duckdb, polars, pyarrow.parquet, typer.main"]
    cases["python -c pass"] = ["-c", "pass"]
    print(f"{options.runs} runs each, alternating; median wall time, median CPU time, peak RSS")
    print("| command | baseline | this tree | ratio (wall, CPU) |")
    print("|---|---|---|---|", flush=True)
    for name, args in cases.items():
        seen: dict[str, list[tuple[float, float, int]]] = {t: [] for t in trees}
        for _ in range(options.runs):
            for tree, path in trees.items():
                if name.endswith(", cold"):  # a copy without its cache, each time
                    shutil.rmtree(fresh, ignore_errors=True)
                    shutil.copytree(options.out, fresh, ignore=shutil.ignore_patterns(METRIC_CACHE_DIR))
                seconds, cpu, peak, code = run(path, args, firsts[tree])
                expected = 1 if "MISSING" in name else 0
                if code != expected:
                    raise SystemExit(f"{name} in {tree}: exit code {code}, expected {expected}")
                seen[tree].append((seconds, cpu, peak))
        cells, wall, cpu = [], {}, {}
        for tree in trees:
            wall[tree] = statistics.median(w for w, _, _ in seen[tree])
            cpu[tree] = statistics.median(c for _, c, _ in seen[tree])
            peak = max(p for _, _, p in seen[tree])
            cells.append(f"{wall[tree]:.2f} s (CPU {cpu[tree]:.2f} s), {peak / MiB:,.0f} MB")
        ratios = f"{wall['baseline'] / wall['this tree']:.1f}x, {cpu['baseline'] / cpu['this tree']:.1f}x"
        print(f"| `{name}` | {cells[0]} | {cells[1]} | {ratios} |", flush=True)


if __name__ == "__main__":
    main()
