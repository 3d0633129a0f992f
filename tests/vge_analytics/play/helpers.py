"""What the tests of `vge_analytics.play` share: a human run on the hand-worked benchmark
that renders no view, a clock, the optimal actions of a task, the run replayed."""

from __future__ import annotations

import json
from pathlib import Path

import polars as pl

import replay
import vge_analytics as va
from replay.env import no_images
from vge_analytics import play

SCREEN = {"image_source": no_images, "image_size": (40, 30)}
"""Episodes here do not look at the views: no rendering."""
KETTLE = "hw_kettle_c"  # 3 goals, C_opt 1 + 2 + 1 (a chain), λ 2
OVEN = "hw_dash_a"  # λ 5


class Clock:
    """Seconds since the epoch, one more per call (a person taking exactly 1 s a step)."""

    def __init__(self, start: float = 1_760_000_000.0) -> None:
        self.now = start

    def __call__(self) -> float:
        self.now += 1.0
        return self.now


def structured(a: replay.Action) -> dict:
    return play.action(a.type.capitalize(), a.coord, a.params)


def optimal_actions(run: play.HumanRun, episode_id: str) -> list[dict]:
    task = run.bench.tasks[episode_id].task
    plan = replay.semantics.setup_episode(run.bench.machine(task.device_id), task).plan
    return [structured(s.action) for s in plan.steps]


def open_run(root: Path, bench: Path, **settings) -> play.HumanRun:
    return play.HumanRun.open(root, bench, clock=Clock(), **SCREEN, **settings)


def lines(path: Path) -> list[dict]:
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def replay_run(run_dir: Path, bench: Path, out: Path) -> dict[str, pl.DataFrame]:
    replay.replay_runs([str(run_dir)], str(bench), str(out), progress=False)
    va.clear_cache()
    return {"steps": va.steps(out), "episodes": va.episodes(out)}
