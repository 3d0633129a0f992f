"""Benchmark of `vge replay` as a user runs it (not a test): whole processes, this checkout
against another one, alternating.

Usage (on the full synthetic benchmark):

    vge synth --out /tmp/vge-full --scale full --seed 0
    .venv/bin/python benchmarks/bench_replay_process.py /tmp/vge-full --base /work/main
        [--workers 1,2] [--rounds 3] [--scratch /tmp/bench-replay] [--rows /tmp/ref-out]
        [--pieces]

Each round runs, for each worker count, `vge replay RUNS --bench BENCH --out OUT --workers N
--no-progress` under `/usr/bin/time -v` with the base checkout's `vge` (`BASE/.venv/bin/vge`)
and with this one's, one after the other (which goes first alternates from round to round),
so that both sides see the same load. Each side keeps its compiled modules (`.pyc`) in a
folder of SCRATCH, written by an unmeasured replay before the rounds, as an installed package
has them (`--no-pyc`: compiled in every process, as where the environment sets
`PYTHONDONTWRITEBYTECODE=1` and no `.pyc` was ever written, this machine's case). Time
measures the whole process tree (interpreter start, imports, the worker processes, the
commit): wall seconds, CPU seconds (user + sys of the process and the workers it waited
for) and peak RSS (of the largest single process); the command itself reports the CPU of
the main process apart from the workers'. With 2 workers on two idle cores the wall time
cannot be below the CPU of the busier process, so its share bounds the rate. On a shared
machine wall time follows the load; CPU seconds per step and the ratio of the two sides
hold. Beside them, in each
round, the floor any replay of these logs pays, in this process: reading, inflating and
decoding every line with msgspec, untyped (to dicts) and typed (`EpisodeLog`).

With `--pieces`, each round also runs the pieces of a 1-worker replay in one fresh process
of this checkout, once and cold, without the runner (`bench_replay_floor.py --one-pass`):
the whole process less that, round by round, is what the runner adds.

The outputs of the two sides are compared file by file (sha256; `.replay/` left out), and
with `--rows REF` the rows of the three tables with those of a reference output directory
(e.g. `/work/baseline/full-out`). Prints a Markdown report (docs/PERFORMANCE.md records one).
"""

from __future__ import annotations

import argparse
import gzip
import hashlib
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

import msgspec

from replay.io import episode_decoder, episodes_file

RUNS_DIR, BENCH_DIR = "runs", "bench"
TABLES = ("steps", "episodes", "goals")
_TIME_FIELDS = {
    "user": r"User time \(seconds\): ([\d.]+)",
    "sys": r"System time \(seconds\): ([\d.]+)",
    "wall": r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): ([\d:.]+)",
    "rss_kb": r"Maximum resident set size \(kbytes\): (\d+)",
}


def _runs(data: Path) -> list[Path]:
    return sorted(d for d in (data / RUNS_DIR).iterdir() if d.is_dir())


def bare_decode(data: Path) -> dict[str, float]:
    """CPU and wall seconds to read, inflate and decode every episode line, untyped and
    typed; the step count."""
    files = [episodes_file(str(d)).local for d in _runs(data)]
    out: dict[str, float] = {}
    untyped = msgspec.json.Decoder()
    for name, decode in (("untyped", untyped.decode), ("typed", episode_decoder.decode)):
        steps = 0
        t0, c0 = time.perf_counter(), time.process_time()
        for path in files:
            raw = path.read_bytes()
            for line in (gzip.decompress(raw) if path.suffix == ".gz" else raw).splitlines():
                if line.strip():
                    got = decode(line)
                    steps += len(got["steps"] if name == "untyped" else got.steps)
        out[f"{name}_wall"] = time.perf_counter() - t0
        out[f"{name}_cpu"] = time.process_time() - c0
        out["steps"] = steps
    return out


def _seconds(clock: str) -> float:
    return sum(float(p) * 60**i for i, p in enumerate(reversed(clock.split(":"))))


SPLIT = """import resource, sys
if __name__ == "__main__":  # what the `vge` script does, then the CPU of this process and
    from vge_analytics.cli import main  # of the workers it waited for

    sys.argv[0] = "vge"
    try:
        code = main()
    except SystemExit as exc:
        code = exc.code
    me, kids = (resource.getrusage(w) for w in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN))
    print("VGE_SPLIT", me.ru_utime + me.ru_stime, kids.ru_utime + kids.ru_stime, file=sys.stderr)
    sys.exit(code)
"""


def _environment(pycache: Path | None) -> dict[str, str]:
    """This process's environment; with `pycache`, Python keeps its compiled modules there
    (`PYTHONPYCACHEPREFIX`) even where the environment says `PYTHONDONTWRITEBYTECODE`."""
    env = dict(os.environ)
    if pycache is not None:
        env.pop("PYTHONDONTWRITEBYTECODE", None)
        env["PYTHONPYCACHEPREFIX"] = str(pycache)
    return env


def replay_process(
    vge: Path,
    data: Path,
    out: Path,
    workers: int,
    tree: Path | None = None,
    pycache: Path | None = None,
) -> dict[str, float]:
    """One `vge replay` of every run into a fresh `out`, under /usr/bin/time -v; `tree`, a
    checkout without a virtualenv of its own, is put first on the module path. The command
    runs as the `vge` script does, from a script (`SPLIT`) that also reports the CPU of the
    main process apart from that of its workers. With `pycache`, the compiled modules are
    kept there, as an installed package keeps its `.pyc` files (`_environment`)."""
    shutil.rmtree(out, ignore_errors=True)
    out.parent.mkdir(parents=True, exist_ok=True)
    split = out.parent / "vge_split.py"
    split.write_text(SPLIT)
    command = [
        "/usr/bin/time", "-v", str(vge.parent / "python"), str(split), "replay",
        *map(str, _runs(data)),
        "--bench", str(data / BENCH_DIR), "--out", str(out),
        "--workers", str(workers), "--no-progress",
    ]  # fmt: skip
    env = _environment(pycache)
    if tree is not None:  # the workers inherit it
        env["PYTHONPATH"] = os.pathsep.join(filter(None, (str(tree), env.get("PYTHONPATH"))))
    cwd = tree if tree is not None else vge.parents[2]
    done = subprocess.run(command, capture_output=True, text=True, cwd=cwd, env=env)
    if done.returncode not in (0, 2):  # 2: some records quarantined
        sys.exit(f"{vge} failed ({done.returncode}):\n{done.stderr[-2000:]}")
    got = {k: re.search(p, done.stderr) for k, p in _TIME_FIELDS.items()}
    if not all(got.values()):
        sys.exit(f"no /usr/bin/time -v report in:\n{done.stderr[-2000:]}")
    main_cpu, workers_cpu = re.findall(r"VGE_SPLIT ([\d.]+) ([\d.]+)", done.stderr)[-1]
    return {
        "main_cpu": float(main_cpu),
        "workers_cpu": float(workers_cpu),
        "wall": _seconds(got["wall"].group(1)),  # type: ignore[union-attr]
        "cpu": float(got["user"].group(1)) + float(got["sys"].group(1)),  # type: ignore[union-attr]
        "rss_mb": int(got["rss_kb"].group(1)) / 1024,  # type: ignore[union-attr]
        "load": os.getloadavg()[0],
    }


def pieces_process(python: Path, data: Path, pycache: Path | None) -> dict[str, float]:
    """The replay's pieces in one fresh process of this checkout, one cold pass without the
    runner (`bench_replay_floor.py --one-pass`): CPU seconds per piece and in all (compiled
    modules kept in `pycache`, as for `replay_process`)."""
    floor = Path(__file__).with_name("bench_replay_floor.py")
    done = subprocess.run(
        [str(python), str(floor), str(data), "--one-pass"],
        capture_output=True, text=True, check=True, cwd=floor.parents[1],
        env=_environment(pycache),
    )  # fmt: skip
    return json.loads(done.stdout.strip().splitlines()[-1])


def digests(out: Path) -> dict[str, str]:
    """sha256 of every output file but the private state, by relative path."""
    return {
        str(p.relative_to(out)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(out.rglob("*"))
        if p.is_file() and ".replay" not in p.relative_to(out).parts
    }


def same_rows(out: Path, ref: Path) -> bool:
    """The three tables hold the same rows, in the same order, as those of `ref`."""
    import pyarrow.dataset as ds

    for table in TABLES:
        a, b = (ds.dataset(d / table, partitioning="hive").to_table() for d in (out, ref))
        a, b = (t.sort_by([("run_id", "ascending")]) for t in (a, b))  # stable: line order
        if not a.equals(b):
            return False
    return True


def parquet_parts(out: Path, run_id: str, scratch: Path, repeat: int = 3) -> dict[str, tuple]:
    """CPU µs per row to write one run's tables as the replay does (a part per batch of
    4,096 lines) and as one part, with the replay's own `write_part`; the least of `repeat`
    tries each. Table -> (rows, parts, µs/row as parts, µs/row as one part)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from replay.io import ROW_GROUP_ROWS, location, write_part

    got = {}
    for table in TABLES:
        files = sorted((out / table / f"run_id={run_id}").glob("*.parquet"))
        parts = [pq.read_table(f) for f in files]
        whole = pa.concat_tables(parts).combine_chunks()
        timed = {}
        for name, tables in (("parts", parts), ("whole", [whole])):
            best = float("inf")
            for _ in range(repeat):
                c0 = time.process_time()
                for k, t in enumerate(tables):
                    write_part(t, location(str(scratch / f"{table}-{k}.parquet")), ROW_GROUP_ROWS)
                best = min(best, time.process_time() - c0)
            timed[name] = 1e6 * best / whole.num_rows
        got[table] = (whole.num_rows, len(parts), timed["parts"], timed["whole"])
    return got


def _row(
    label: str, runs: list[dict[str, float]], steps: int, cores: int, base: list[dict] | None
) -> str:
    """A Markdown row: medians over the rounds; `cores` busy at most (the CPU-bound rate)."""
    wall = statistics.median(r["wall"] for r in runs)
    cpu = statistics.median(r["cpu"] for r in runs)
    rss = max(r["rss_mb"] for r in runs)
    ratio = ""
    if base is not None:
        b_wall = statistics.median(r["wall"] for r in base)
        b_cpu = statistics.median(r["cpu"] for r in base)
        ratio = f"{cpu / b_cpu:.3f} / {wall / b_wall:.2f}"
    tries = ", ".join(f"{r['cpu']:.2f}" for r in runs)
    main = statistics.median(r["main_cpu"] for r in runs)
    others = statistics.median(r["workers_cpu"] for r in runs)
    return (
        f"| {label} | {wall:.2f} | {cpu:.2f} ({tries}) | {main:.2f} / {others:.2f} | "
        f"{1e6 * cpu / steps:.2f} | {steps / wall:,.0f} | {cores * steps / cpu:,.0f} | "
        f"{steps / max(main, others, cpu / cores):,.0f} | {rss:.0f} | {ratio} |"
    )


PIECES = (
    ("start", "start: interpreter and the imports a worker needs"),
    ("open", "opening BENCH"),
    ("read", "reading and inflating the lines"),
    ("decode", "decoding (`decode_episode_line`: the kernel's structs, msgspec for the rest)"),
    ("prepare", "preparing the lines (compiling and planning met cold, look-ups)"),
    ("kernel_arrow", "the kernel and its Arrow tables (its tables per machine met cold)"),
    ("parquet_parts", "Parquet, a part per batch and table"),
)


def _pieces_report(pieces: list[dict[str, float]], whole: list[dict[str, float]], steps: int):
    """The pieces of one cold pass beside the whole 1-worker process of the same rounds."""
    print("\n| 1 worker, this checkout (median of the rounds) | CPU s | CPU µs/step |")
    print("|---|---:|---:|")
    for key, label in PIECES:
        cpu = statistics.median(p[key] for p in pieces)
        print(f"| {label} | {cpu:.2f} | {1e6 * cpu / steps:.2f} |")
    total = statistics.median(p["total"] for p in pieces)
    # both before the interpreter's teardown: the pieces' process is timed from inside, the
    # replay's at the end of its command (`SPLIT`); the replay's teardown is its CPU less that
    one = statistics.median(r["main_cpu"] for r in whole)
    down = statistics.median(r["cpu"] - r["main_cpu"] for r in whole)
    print(f"| **the pieces, one process, no runner** | {total:.2f} | {1e6 * total / steps:.2f} |")
    print(
        f"| **`vge replay --workers 1`, whole process** (teardown left out: {down:.2f} s) |"
        f" {one:.2f} | {1e6 * one / steps:.2f} |"
    )
    gaps = [r["main_cpu"] - p["total"] for r, p in zip(whole, pieces, strict=True)]
    each = ", ".join(f"{g:+.2f}" for g in gaps)
    gap = statistics.median(gaps)
    print(f"| what the runner adds (each round: {each}) | {gap:+.2f} | {1e6 * gap / steps:+.2f} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("data", type=Path, help="directory with bench/ and runs/")
    parser.add_argument("--base", type=Path, required=True, help="checkout to compare with")
    parser.add_argument("--workers", default="1,2")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--scratch", type=Path, default=Path("/tmp/bench-replay-process"))
    parser.add_argument("--rows", type=Path, help="reference output directory to compare rows")
    parser.add_argument(
        "--parts", metavar="RUN_ID", help="also time Parquet parts against one part for a run"
    )
    parser.add_argument(
        "--pieces",
        action="store_true",
        help="also run the pieces of a 1-worker replay without the runner, once per round",
    )
    parser.add_argument(
        "--no-pyc",
        dest="pyc",
        action="store_false",
        help="compile the modules in every process, as PYTHONDONTWRITEBYTECODE=1 without "
        ".pyc files does (default: each side keeps its compiled modules under SCRATCH, "
        "written by an unmeasured replay first, as an installed package has them)",
    )
    args = parser.parse_args()
    here = Path(__file__).parents[1] / ".venv/bin/vge"
    # a base checkout without a virtualenv (a `git worktree add` of a commit, its kernel
    # built in place) runs with this one's, the base tree first on the module path
    base_venv = args.base / ".venv/bin/vge"
    base_tree = None if base_venv.exists() else args.base
    sides = {"base": base_venv if base_tree is None else here, "this": here}
    trees = {"base": base_tree, "this": None}
    workers = [int(w) for w in args.workers.split(",") if w]
    results: dict[tuple[str, int], list[dict[str, float]]] = {}
    floors: list[dict[str, float]] = []
    load0 = " / ".join(f"{x:.1f}" for x in os.getloadavg())
    pieces: list[dict[str, float]] = []
    pycache = {side: args.scratch / f"pycache-{side}" if args.pyc else None for side in sides}
    if args.pyc:  # written once, unmeasured
        for side, vge in sides.items():
            replay_process(vge, args.data, args.scratch / "warm", 2, trees[side], pycache[side])
    for round_ in range(args.rounds):
        floors.append(bare_decode(args.data))
        if args.pieces:
            pieces.append(pieces_process(here.parent / "python", args.data, pycache["this"]))
        for w in workers:
            order = list(sides.items())
            for side, vge in order if round_ % 2 == 0 else order[::-1]:  # who goes first alternates
                out = args.scratch / f"out-{side}-{w}"
                results.setdefault((side, w), []).append(
                    replay_process(vge, args.data, out, w, trees[side], pycache[side])
                )
    steps = int(floors[0]["steps"])
    identical = all(
        digests(args.scratch / f"out-base-{w}") == digests(args.scratch / f"out-this-{w}")
        for w in workers
    )
    print(f"## `vge replay`, whole process: {args.data}, base {args.base}\n")
    print(
        f"- {steps:,} steps; {args.rounds} rounds, base and this alternating; {os.cpu_count()}"
        f" CPUs; compiled modules {'kept (.pyc)' if args.pyc else 'compiled in every process'};"
        f" load average at the start {load0}, at the end "
        + " / ".join(f"{x:.1f}" for x in os.getloadavg())
        + "\n"
    )
    print(
        "| measure | wall s | CPU s (each round) | CPU s: main / workers | CPU µs/step |"
        " steps/s (wall) | steps/s if its CPU were spread over idle cores |"
        " steps/s on idle cores, at most (the busier process) | peak RSS MB |"
        " this / base: CPU / wall |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---|")
    for name in ("untyped", "typed"):
        cpu = statistics.median(f[f"{name}_cpu"] for f in floors)
        wall = statistics.median(f[f"{name}_wall"] for f in floors)
        print(
            f"| bare decode, msgspec {name} | {wall:.2f} | {cpu:.2f} | | "
            f"{1e6 * cpu / steps:.2f} | {steps / wall:,.0f} | | | | |"
        )
    for w in workers:
        for side in sides:
            base = results[("base", w)] if side == "this" else None
            cores = min(w, os.cpu_count() or 1)
            label = f"`vge replay --workers {w}`, {side}"
            print(_row(label, results[(side, w)], steps, cores, base))
    untyped = statistics.median(f["untyped_cpu"] for f in floors)
    print()
    for side in sides:
        if 1 in workers:
            one = statistics.median(r["cpu"] for r in results[(side, 1)])
            print(f"- {side}, 1 worker: {one / untyped:.1f}x the CPU of a bare untyped decode")
    print(f"- outputs of base and this: {'byte-identical' if identical else 'DIFFER'}")
    if pieces and 1 in workers:
        _pieces_report(pieces, results[("this", 1)], steps)
    if args.parts:
        print(f"\n| {args.parts}: table | rows | parts | CPU µs/row as parts | as one part |")
        print("|---|---:|---:|---:|---:|")
        out = args.scratch / f"out-this-{workers[-1]}"
        for table, (rows, n, parts, whole) in parquet_parts(out, args.parts, args.scratch).items():
            print(f"| {table} | {rows:,} | {n} | {parts:.2f} | {whole:.2f} |")
    if args.rows is not None:
        checked = [same_rows(args.scratch / f"out-this-{w}", args.rows) for w in workers]
        print(f"- rows equal to {args.rows}: {'yes' if all(checked) else 'NO'}")


if __name__ == "__main__":
    main()
