"""Benchmark of what a replay cannot avoid (not a test): the CPU each piece of `vge replay`'s
work costs on its own, measured in a fresh process, so that the whole-process figures of
`bench_replay_process.py` can be set against the sum of their parts.

Usage (on the full synthetic benchmark):

    vge synth --out /tmp/vge-full --scale full --seed 0
    .venv/bin/python benchmarks/bench_replay_floor.py /tmp/vge-full [--repeat 3]

Each try runs in a fresh interpreter (`--inner`), one after the other:
- once per process: the interpreter and the imports a worker needs (`replay.io._batch`),
  opening BENCH, compiling every machine the tasks use, planning every task (`setup_episode`),
  and the kernel's own tables per machine and goal (the first pass over the batches, less
  the second);
- per step, over every batch of every run as the replay cuts them (4,096 lines): reading
  and inflating the lines (`iter_lines`), decoding them as a batch does
  (`decode_episode_line`: into the kernel's structs, or by msgspec with the depth check for
  what it declines), the rest of preparing them (look-ups, the plan from the cache), the
  kernel's replay and its Arrow tables (`replay_kernel`), the Parquet parts as the replay writes
  them (`write_part`, a part per batch and table) and, beside them, each run's tables
  written as one part (what bigger parts could save at most);
- the floor of a bare untyped decode, as `bench_replay_process.py` measures it.
The least CPU of `--repeat` tries is kept for each piece. Prints a Markdown report.

With `--one-pass`, one fresh process instead runs the pieces once, cold, as a 1-worker
replay meets them, and prints them as JSON with the process's CPU ("total"):
`bench_replay_process.py --pieces` runs it in each round beside the whole process, so that
what the runner adds is the difference of two measurements made minutes apart.
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

PER_PROCESS = ("start", "open", "compile", "plan", "kernel_tables")
PER_STEP = ("read", "decode", "prepare", "kernel_arrow", "parquet_parts")
BATCH_LINES = 4096  # the replay's batch (`io/_job.py`)


def _runs(data: Path) -> list[Path]:
    return sorted(d for d in (data / "runs").iterdir() if d.is_dir())


def _batches(data: Path, got: dict[str, float]):
    """(run name, lines) of every batch of every run, cut as the replay cuts them; the CPU
    of reading and inflating them added to got["read"]."""
    from replay.io import episodes_file, iter_lines

    for run in _runs(data):
        lines = iter_lines(episodes_file(str(run)))
        while True:
            c0 = time.process_time()
            batch = list(itertools.islice(lines, BATCH_LINES))
            got["read"] += time.process_time() - c0
            if not batch:
                break
            yield run.name, batch


def _pass(data: Path, scratch: Path, state, got: dict[str, float], write: bool) -> int:
    """One pass over every batch, each piece timed into `got`; the steps replayed. What it
    does to a line is what `replay_batch` does to a good one (the checks that quarantine a
    bad one are look-ups that find nothing wrong here)."""
    from replay.io import ROW_GROUP_ROWS, Ready, decode_episode_line, location, write_part
    from replay.kernel import EpisodeInput, replay_kernel
    from replay.semantics import episode_lambda

    bench = state.bench
    steps = 0
    for index, (run, lines) in enumerate(_batches(data, got)):
        c0 = time.process_time()
        logs = []
        for _, raw in lines:  # as a batch reads a line (`_batch._prepare_lines`)
            logs.append(decode_episode_line(raw))
        c1 = time.process_time()
        episodes = []
        for log in logs:  # the checks once per episode and process, as in a batch
            ready = state.ready.get(log.episode_id)
            if ready is None:
                task = bench.tasks[log.episode_id].task
                bench.no_machine(task.device_id)
                machine = bench.machine(task.device_id)
                ready = Ready(machine, task, state.setup(machine, task))
                state.remember_ready(ready)
            machine, task, setup = ready
            lam = episode_lambda(task, None, None)
            episodes.append(EpisodeInput(machine, task, setup, log, lam))
        c2 = time.process_time()
        made = replay_kernel(episodes, run_id=run, model="m", agent_kind="a")
        c3 = time.process_time()
        if write:
            for table, rows in zip(("steps", "episodes", "goals"), made[:3], strict=True):
                if rows.num_rows:
                    path = scratch / run / table / f"part-{index:05d}.parquet"
                    path.parent.mkdir(parents=True, exist_ok=True)
                    write_part(rows, location(str(path)), ROW_GROUP_ROWS)
        got["parquet_parts"] += time.process_time() - c3
        got["decode"] += c1 - c0
        got["prepare"] += c2 - c1
        got["kernel_arrow"] += c3 - c2
        steps += made.steps.num_rows
    return steps


def _one_part(scratch: Path) -> float:
    """CPU seconds to write each run's tables, read back from its parts, as one part."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from replay.io import ROW_GROUP_ROWS, location, write_part

    spent = 0.0
    for run in sorted(p for p in scratch.iterdir() if p.is_dir()):
        for table in ("steps", "episodes", "goals"):
            parts = sorted((run / table).glob("part-*.parquet"))
            whole = pa.concat_tables([pq.read_table(p) for p in parts]).combine_chunks()
            c0 = time.process_time()
            write_part(whole, location(str(run / f"{table}-whole.parquet")), ROW_GROUP_ROWS)
            spent += time.process_time() - c0
    return spent


def inner(data: Path) -> dict[str, float]:
    """Every piece, measured in this fresh process, in the order a replay meets them."""
    import gc

    got = dict.fromkeys(PER_PROCESS + PER_STEP, 0.0)
    got["start"] = time.process_time()  # the interpreter and this script so far
    c0 = time.process_time()
    import replay.io
    import replay.kernel  # noqa: F401  (what a worker imports: the kernel, pyarrow, numpy)

    replay.io.replay_batch  # noqa: B018  (loads the batch module, as a worker does)
    got["start"] += time.process_time() - c0
    from replay.semantics import setup_episode

    gc.disable()  # as in a batch (`replay_batch`)
    c0 = time.process_time()
    state = replay.io.worker_state(str(data / "bench"))
    got["open"] = time.process_time() - c0
    bench = state.bench
    c0 = time.process_time()
    machines = {}
    for entry in bench.tasks.values():
        device = entry.task.device_id
        if device not in machines and bench.no_machine(device) is None:
            machines[device] = bench.machine(device)
    got["compile"] = time.process_time() - c0
    c0 = time.process_time()
    for entry in bench.tasks.values():
        if entry.task.device_id in machines:
            state.setups[entry.task.episode_id] = setup_episode(
                machines[entry.task.device_id], entry.task
            )
    got["plan"] = time.process_time() - c0
    with tempfile.TemporaryDirectory(prefix="vge-floor-") as tmp:
        cold = dict.fromkeys(PER_STEP, 0.0)
        _pass(data, Path(tmp), state, cold, write=False)
        gc.freeze()
        steps = _pass(data, Path(tmp), state, got, write=True)
        got["kernel_tables"] = cold["kernel_arrow"] - got["kernel_arrow"]
        got["parquet_one_part"] = _one_part(Path(tmp))
    got["steps"] = steps
    got["untyped"] = _bare_untyped(data)
    return got


def one_pass(data: Path) -> dict[str, float]:
    """The pieces as one replay with 1 worker meets them, in this fresh process, without
    the runner: the imports a worker needs, opening BENCH, then one pass over every batch
    (compiling, planning and the kernel's tables met cold, in the per-step pieces), the
    collector paused as in a batch. "total" is this process's CPU, its start included:
    what `vge replay --workers 1` would cost if the runner (the reading thread, the
    reports, the quarantine, the hashes, the commits, the CLI) cost nothing."""
    import gc

    got = dict.fromkeys(PER_STEP, 0.0)
    import replay.io

    replay.io.replay_batch  # noqa: B018  (loads the batch module, as a worker does)
    got["start"] = time.process_time()  # the interpreter and the imports
    gc.disable()
    c0 = time.process_time()
    state = replay.io.worker_state(str(data / "bench"))
    got["open"] = time.process_time() - c0
    with tempfile.TemporaryDirectory(prefix="vge-floor-") as tmp:
        got["steps"] = _pass(data, Path(tmp), state, got, write=True)
    got["total"] = time.process_time()
    return got


def _bare_untyped(data: Path) -> float:
    """CPU seconds of `bench_replay_process.bare_decode`'s untyped floor."""
    sys.path.insert(0, str(Path(__file__).parent))
    from bench_replay_process import bare_decode

    return bare_decode(data)["untyped_cpu"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("data", type=Path, help="directory with bench/ and runs/")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--inner", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument(
        "--one-pass", action="store_true", help="print the pieces of one cold pass as JSON"
    )
    args = parser.parse_args()
    if args.one_pass:
        print(json.dumps(one_pass(args.data)))
        return
    if args.inner:
        print(json.dumps(inner(args.data)))
        return
    tries = []
    for _ in range(args.repeat):
        done = subprocess.run(
            [sys.executable, __file__, str(args.data), "--inner"],
            capture_output=True, text=True, check=True,
        )  # fmt: skip
        tries.append(json.loads(done.stdout.strip().splitlines()[-1]))
    best = {k: min(t[k] for t in tries) for k in tries[0]}
    report(best, tries, args)


def report(best: dict[str, float], tries: list[dict], args: argparse.Namespace) -> None:
    steps = int(best["steps"])
    us = {k: 1e6 * v / steps for k, v in best.items() if k != "steps"}
    load = " / ".join(f"{x:.1f}" for x in os.getloadavg())
    print(f"## What a replay cannot avoid: {args.data}\n")
    print(f"- {steps:,} steps; least CPU of {args.repeat} fresh processes; load average {load}\n")
    print("| piece | CPU s | CPU µs/step | each try (s) |")
    print("|---|---:|---:|---:|")
    for k in (*PER_PROCESS, *PER_STEP, "parquet_one_part", "untyped"):
        each = ", ".join(f"{t[k]:.2f}" for t in tries)
        print(f"| {k} | {best[k]:.2f} | {us[k]:.2f} | {each} |")
    fixed = sum(us[k] for k in PER_PROCESS)
    per_step = sum(us[k] for k in PER_STEP)
    fixed_two = fixed + us["start"] + us["open"]
    print()
    print(f"- 1 worker, the sum: {fixed + per_step:.2f} µs/step ({fixed:.2f} once per process,")
    print(f"  {per_step:.2f} per step), {(fixed + per_step) / us['untyped']:.1f}x a bare untyped")
    print(f"  decode ({us['untyped']:.2f} µs/step); 5x is {5 * us['untyped']:.2f} µs/step")
    print(
        f"- 2 workers, the sum with a second process's start and BENCH: {fixed_two + per_step:.2f}"
    )
    print(f"  µs/step: at most {2e6 / (fixed_two + per_step):,.0f} steps/s on two idle cores;")
    print("  250,000 steps/s needs 8.00 µs/step, evenly shared")
    saved = us["parquet_parts"] - us["parquet_one_part"]
    print(
        f"- one Parquet part per run and table instead of one per batch: {saved:.2f} µs/step less"
    )


if __name__ == "__main__":
    main()
