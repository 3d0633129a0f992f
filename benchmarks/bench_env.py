"""Steps per second of the Gymnasium environments, alone and in vector envs (not a test).

    .venv/bin/python benchmarks/bench_env.py [--bench logs/bench] [--steps 2000]
        [--envs 2,4] [--size 64] [--images rendered|none]

For `vge/DeviceRL-v0` (sampled actions, seeded) and `vge/Device-v0` (the same actions as
structured ones), or their `vge/Rendered...` ids with `--images rendered`: `gymnasium.make_vec` with `sync` vectorization of one environment, then
`sync` and `async` (Gymnasium's defaults: shared memory, the platform's start method) for
each count of `--envs`. Environment steps per second (a vector step of N envs counts N), by
the wall clock and per CPU second of this process and the async env's workers (steadier
under load from other processes), for a first pass of the actions from a seeded reset, in
which each environment decodes and resizes every view it meets (about 20 ms each), and for
the same pass again, every view in the environment's cache. Views: `--images rendered`
(`vge/RenderedDeviceRL-v0` and `vge/RenderedDevice-v0` of `vge_analytics.rendered_envs`;
every view is rendered into the disk cache first), or `none`
(the blank canvas: the episode logic and the image copy alone). Prints a markdown table.
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
import sys
import time
from pathlib import Path

import gymnasium
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import replay  # noqa: E402
from replay.env import ENV_ID, RL_ENV_ID, no_images  # noqa: E402
from vge_analytics import rendered_envs, synth  # noqa: E402

gymnasium.register_envs(rendered_envs)  # the ids with the rendered views


def _cpu(envs: gymnasium.vector.VectorEnv) -> float:
    """CPU seconds of this process and of the async env's workers (still running, so not in
    `RUSAGE_CHILDREN`: read from /proc)."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    seconds = own.ru_utime + own.ru_stime
    tick = os.sysconf("SC_CLK_TCK")
    for process in getattr(envs, "processes", ()):
        fields = Path(f"/proc/{process.pid}/stat").read_text().rsplit(")", 1)[1].split()
        seconds += (int(fields[11]) + int(fields[12])) / tick  # utime, stime
    return seconds


def _actions(rl_id: str, text: bool, n: int, steps: int, size: int, bench: str) -> list:
    """`steps` vector actions of `n` environments: sampled RL actions, or their structured
    form for the text environment (the same steps)."""
    rl = gymnasium.make(rl_id, bench=bench, image_width=size, image_height=size).unwrapped
    space = gymnasium.spaces.MultiDiscrete(np.tile(rl.action_space.nvec, (n, 1)), seed=0)
    drawn = [space.sample() for _ in range(steps)]
    if not text:
        return drawn
    return [tuple(rl.structured_action(a) for a in batch) for batch in drawn]


def _pass(envs: gymnasium.vector.VectorEnv, actions: list) -> tuple[float, float]:
    """Wall and CPU seconds of one pass: reset with seed 0, then every action."""
    envs.reset(seed=0)
    wall, cpu = time.perf_counter(), _cpu(envs)
    for batch in actions:
        envs.step(batch)
    return time.perf_counter() - wall, _cpu(envs) - cpu


def prerender(bench: str) -> int:
    """Render every view of every device once, so each measurement finds them in the disk
    cache (otherwise the first configuration pays for the rendering)."""
    opened = replay.Benchmark.open(bench)
    source = synth.image_source(bench)
    views = 0
    for device_id in sorted(opened.ssm_paths):
        machine = opened.machine(device_id)
        for view in machine.views:
            views += source(machine, view) is not None
    return views


def _ids(images: str) -> tuple[str, str]:
    """(RL id, text id) showing the views as `--images` says."""
    if images == "rendered":
        return rendered_envs.RENDERED_RL_ENV_ID, rendered_envs.RENDERED_ENV_ID
    return RL_ENV_ID, ENV_ID


def measure(env_id: str, mode: str, n: int, args: argparse.Namespace) -> list[float]:
    """Steps per second (wall, CPU) of a first pass, in which each environment decodes every
    view it meets, and of the same pass again (same seed, same actions: every view cached)."""
    options = {"bench": args.bench, "image_width": args.size, "image_height": args.size}
    if args.images == "none":
        options["image_source"] = no_images
    rl_id, text_id = _ids(args.images)
    actions = _actions(rl_id, env_id == text_id, n, args.steps // n, args.size, args.bench)
    envs = gymnasium.make_vec(env_id, num_envs=n, vectorization_mode=mode, **options)
    try:
        passes = [_pass(envs, actions), _pass(envs, actions)]
    finally:
        envs.close()
    done = len(actions) * n
    return [done / seconds for pair in passes for seconds in pair]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bench", default=str(ROOT / "logs" / "bench"))
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--envs", default="2,4")
    parser.add_argument("--size", type=int, default=64)
    parser.add_argument("--images", choices=("rendered", "none"), default="rendered")
    args = parser.parse_args()
    counts = [int(n) for n in args.envs.split(",")]
    if args.images == "rendered":
        print(f"{prerender(args.bench)} views rendered and cached")
    print(
        f"{args.steps} steps, {args.size} x {args.size} images ({args.images}), "
        f"{os.cpu_count()} CPUs, Python {platform.python_version()}, "
        f"Gymnasium {gymnasium.__version__}, load average {os.getloadavg()[0]:.1f}\n"
    )
    print(
        "| environment | vectorization | envs | first pass: steps/s | per CPU s | cached: steps/s | per CPU s |"
    )
    print("|---|---|---:|---:|---:|---:|---:|")
    for env_id in _ids(args.images):
        for mode, n in [("sync", 1)] + [(m, n) for m in ("sync", "async") for n in counts]:
            rates = " | ".join(f"{r:,.0f}" for r in measure(env_id, mode, n, args))
            print(f"| `{env_id}` | {mode} | {n} | {rates} |", flush=True)


if __name__ == "__main__":
    main()
