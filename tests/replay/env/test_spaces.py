"""The spaces of `vge/Device-v0`: bounded by the benchmark's maxima, worked out by hand from
the hand-worked cases, and laid out in shared memory, so an async vector env runs with its
default options; a vector env's observations and infos are the single environments'."""

from __future__ import annotations

import copy
import json
import math
import multiprocessing
from pathlib import Path

import gymnasium
import numpy as np
import pytest
from gymnasium import spaces
from gymnasium.vector.utils import (
    create_shared_memory,
    read_from_shared_memory,
    write_to_shared_memory,
)

import replay
from replay.env import ENV_ID, DeviceEnv, bench_bounds, no_images
from replay.env._textspaces import AnyText, ViewNames

from ..conftest import CASES, Sample

SIZE = {"image_width": 32, "image_height": 24}
LOGS_BENCH = Path(__file__).resolve().parents[3] / "logs" / "bench"


def _hand_worked_maxima() -> tuple[float, int]:
    """The largest `B_global = λ · L_opt` and the most goals among the hand-worked cases, from
    the numbers written in the case files (every case's task has its own λ)."""
    budgets, goals = [], []
    for path in sorted(CASES.glob("*.json")):
        doc = json.loads(path.read_text())
        if "expected" in doc:
            budgets.append(doc["task"]["lambda"] * doc["expected"]["episode"]["L_opt"])
            goals.append(len(doc["task"]["goals"]))
    return max(budgets), max(goals)


def test_the_bounds_are_the_benchmarks_maxima(sample: Sample) -> None:
    budget, goals = _hand_worked_maxima()
    # hw_dash_d: λ 8, L_opt 3; hw_kettle_c: three goals. The sample's two unplayable tasks
    # (an unknown device, an unknown goal) are passed over.
    assert (budget, goals) == (24, 3)
    bounds = bench_bounds(replay.Benchmark.open(sample.bench), lam=None)
    assert (bounds.budget, bounds.steps, bounds.goals) == (24.0, 24, 3)
    # The odd episode id `hw_dash_a-c0 #odd/id` (20 characters); kettle_f's instruction.
    assert (bounds.episode_id, bounds.instruction) == (len("hw_dash_a-c0 #odd/id"), 41) == (20, 41)


def test_the_bounds_follow_the_runs_lambda() -> None:
    """The bundled benchmark's tasks have no λ of their own, and carry their C_opt: the run's
    λ (5 by default) times the largest L_opt, 12."""
    tasks = [json.loads(line) for line in (LOGS_BENCH / "tasks.jsonl").read_text().splitlines()]
    longest = max(sum(t["c_opt"]) for t in tasks)
    assert longest == 12 and all("lambda" not in t for t in tasks)
    bench = replay.Benchmark.open(LOGS_BENCH)
    assert bench_bounds(bench, None).budget == 5 * longest == 60
    lean = bench_bounds(bench, 2.25)
    assert (lean.budget, lean.steps) == (2.25 * 12, math.ceil(2.25 * 12)) == (27.0, 27)
    assert lean.goals == max(len(t["goals"]) for t in tasks) == 4


def test_every_space_is_bounded_by_the_benchmark(sample: Sample) -> None:
    space = DeviceEnv(sample.bench, image_source=no_images, **SIZE).observation_space
    assert space["step"] == spaces.Discrete(25)  # 0..24 steps taken
    assert space["goal_index"] == spaces.Discrete(4)  # 0..3 (3: every goal completed)
    assert space["n_goals"] == spaces.Discrete(3, start=1)
    assert space["budget_global_left"] == spaces.Box(-1.0, 24.0, shape=(), dtype=np.float64)
    texts = {key: space[key].max_length for key in space if isinstance(space[key], AnyText)}
    assert texts == {
        "episode_id": 20,
        "view": len("back_bottom"),
        "instruction": 41,
        "feedback": 100_000,
        "feedback_kind": len("dashboard_unlocked"),
    }
    # The numbers flatten to 2 + 25 + 4 + 3 + 2 values (Discrete(2**31) made it 2 GiB).
    numbers = spaces.Dict(
        {
            k: space[k]
            for k in space
            if k != "image" and not isinstance(space[k], (AnyText, ViewNames))
        }
    )
    assert spaces.flatdim(numbers) == 2 + 25 + 4 + 3 + 2


@pytest.mark.parametrize(
    "text", ["", "Open the lid.", "Ouvrez le couvercle à 90 °C ✓ 🫖", "lone \ud800 surrogate"]
)
def test_any_text_goes_through_shared_memory(text: str) -> None:
    space = AnyText(40, min_length=0)
    shared = create_shared_memory(space, n=3, ctx=multiprocessing.get_context())
    live = read_from_shared_memory(space, shared, n=3)
    write_to_shared_memory(space, 1, text, shared)
    write_to_shared_memory(space, 2, "x" * 40, shared)
    assert copy.deepcopy(live) == ("", text, "x" * 40)
    write_to_shared_memory(space, 2, "y", shared)  # the rows are read when they are read
    assert live[2] == "y" and len(live) == 3
    with pytest.raises(ValueError, match="longer than 40"):
        write_to_shared_memory(space, 0, "z" * 41, shared)


def test_view_names_go_through_shared_memory() -> None:
    space = ViewNames(seed=0)
    shared = create_shared_memory(space, n=2, ctx=multiprocessing.get_context())
    standard = ("front", "back", "left", "right", "top", "bottom", "front_top", "back_bottom")
    write_to_shared_memory(space, 0, (*standard, "dashboard"), shared)
    write_to_shared_memory(space, 1, ("top", "front"), shared)
    assert copy.deepcopy(read_from_shared_memory(space, shared, n=2)) == (
        (*standard, "dashboard"),
        ("top", "front"),
    )
    assert all(space.contains(space.sample()) for _ in range(20))
    assert not space.contains(("front", "front")) and not space.contains(("side",))


def _same(vector_value: object, single: object) -> bool:
    if isinstance(single, (str, tuple)):
        return vector_value == single
    return bool(np.array_equal(vector_value, single))


ACTIONS = ["Action: Switch_view(params=[back])", "Action: Press(coord=[500, 500], params=[0])"]


@pytest.mark.parametrize(
    ("mode", "vector_kwargs"),
    [("sync", {}), ("async", {}), ("async", {"context": "spawn"})],
    ids=["sync", "async", "async-spawn"],
)
def test_a_vector_env_of_two_gives_the_single_envs_values(
    sample: Sample, mode: str, vector_kwargs: dict
) -> None:
    """Default options (shared memory for the async env); with `spawn` the workers register
    the text layouts themselves, by importing the environment."""
    envs = gymnasium.make_vec(
        ENV_ID, num_envs=2, vectorization_mode=mode, vector_kwargs=vector_kwargs,
        bench=str(sample.bench), **SIZE,
    )  # fmt: skip
    singles = [gymnasium.make(ENV_ID, bench=str(sample.bench), **SIZE) for _ in range(2)]
    try:
        batch, _ = envs.reset(seed=7)
        alone = [env.reset(seed=7 + i)[0] for i, env in enumerate(singles)]
        assert batch["episode_id"] != (alone[0]["episode_id"],) * 2  # two episodes
        for action in ACTIONS:
            batch, rewards, _, _, infos = envs.step((action, action))
            steps = [env.step(action) for env in singles]
            for i, (obs, reward, terminated, truncated, info) in enumerate(steps):
                assert not (terminated or truncated)
                assert rewards[i] == reward
                for key, value in obs.items():
                    assert _same(batch[key][i], value), key
                for key in replay.env.STEP_FIELDS:
                    assert infos.get(f"_{key}", [False, False])[i] == (key in info), key
                    if key in info:
                        assert _same(infos[key][i], info[key]), key
        assert envs.observation_space.contains(batch)
    finally:
        envs.close()
