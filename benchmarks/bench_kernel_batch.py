"""Benchmark of the kernel alone (not a test): one batch of a run's first episodes, decoded
and planned beforehand, through `replay_kernel` (the compiled replay and its Arrow tables),
warm.

Usage:

    .venv/bin/python benchmarks/bench_kernel_batch.py /work/baseline/full [--run sim-vlm-a]
        [--episodes 4096] [--repeat 9] [--lines]

prints the least and median CPU per step of `replay_kernel` over `--repeat` tries, after a
first cold call. The lines are decoded by msgspec (`EpisodeLog`s); with `--lines`, straight
into the kernel's structs where `decode_line` takes them (`LogLine`s; msgspec the others), as
`vge replay` decodes them. For instruction counts, which hold on a noisy machine, run it
under `valgrind --tool=callgrind` with `--repeat 0` (the cold call only) and `--repeat 1`
(one warm try more): the difference of the two totals is one warm `replay_kernel`, and
`callgrind_annotate --inclusive=yes` gives `replay_batch`'s share.
"""

from __future__ import annotations

import argparse
import gc
import itertools
import statistics
import time
from pathlib import Path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("data", type=Path, help="directory with bench/ and runs/")
    parser.add_argument("--run", default="sim-vlm-a")
    parser.add_argument("--episodes", type=int, default=4096)
    parser.add_argument("--repeat", type=int, default=9)
    parser.add_argument("--lines", action="store_true", help="decode_line first, as vge replay")
    args = parser.parse_args()

    import replay.io
    from replay.kernel import EpisodeInput, LogLine, decode_line, replay_kernel
    from replay.semantics import episode_lambda

    gc.disable()  # as in a batch (`replay.io.replay_batch`)
    state = replay.io.worker_state(str(args.data / "bench"))
    path = replay.io.episodes_file(str(args.data / "runs" / args.run))
    lines = list(itertools.islice(replay.io.iter_lines(path), args.episodes))
    episodes = []
    taken = 0
    for _, raw in lines:
        log = decode_line(raw) if args.lines else None
        taken += log is not None
        if log is None:
            log = replay.io.episode_decoder.decode(raw)
        task = state.bench.tasks[log.episode_id].task
        machine = state.bench.machine(task.device_id)
        setup = state.setup(machine, task)
        episodes.append(EpisodeInput(machine, task, setup, log, episode_lambda(task, None, None)))
    steps = sum(len(e.log) if isinstance(e.log, LogLine) else len(e.log.steps) for e in episodes)
    replay_kernel(episodes, run_id="r", model="m", agent_kind="a")  # cold: machines, goals
    got = []
    for _ in range(args.repeat):
        c0 = time.process_time()
        replay_kernel(episodes, run_id="r", model="m", agent_kind="a")
        got.append((time.process_time() - c0) / steps * 1e6)
    print(f"{args.run}: {len(episodes):,} episodes, {steps:,} steps ({taken:,} LogLines)")
    if got:
        print(
            f"replay_kernel: least {min(got):.3f}, median {statistics.median(got):.3f} "
            f"µs/step of CPU ({args.repeat} tries)"
        )


if __name__ == "__main__":
    main()
