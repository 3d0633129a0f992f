"""`vge/DeviceRL-v0`: Gymnasium's checker, the action grid and parameter table worked by hand,
a hand-worked episode played with integers, sampled actions that always parse, the same
steps as `vge/Device-v0`, `FlattenObservation` (its size worked out from the benchmark, under
a memory bound) and vector envs."""

from __future__ import annotations

import json
import sys
import warnings
from collections import Counter
from pathlib import Path

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import replay
from replay.env import (
    CHOICES,
    PARAMETERS,
    RL_ENV_ID,
    DeviceRLEnv,
    cell_centre,
    log_step_of,
    no_images,
)
from replay.semantics import DISPLAY_NAMES, normalize_params

from ...bounded import run_bounded
from ..conftest import Sample

SIZE = {"image_width": 32, "image_height": 24}
LOGS_BENCH = Path(__file__).resolve().parents[3] / "logs" / "bench"
PUSH, SWITCH_VIEW, TIMED_WAIT = 2, 5, 6


def _rl(bench: Path | str, **kwargs) -> DeviceRLEnv:
    return DeviceRLEnv(bench, image_source=no_images, **(SIZE | kwargs))


def test_passes_gymnasiums_checker(sample: Sample) -> None:
    env = gymnasium.make(RL_ENV_ID, bench=str(sample.bench), **SIZE)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped)
    assert [str(w.message) for w in caught] == []
    assert env.action_space == gymnasium.spaces.MultiDiscrete([7, 100, 100, 9])
    env.close()


def test_the_grid_and_the_parameter_table_by_hand(sample: Sample) -> None:
    env = _rl(sample.bench)
    assert [cell_centre(i, 100) for i in (0, 37, 82, 99)] == [5.0, 375.0, 825.0, 995.0]
    assert [cell_centre(i, 3) for i in range(3)] == [1000 / 6, 500.0, 5000 / 6]
    decoded = {
        (0, 37, 82, 1): {"type": "Press", "coord": [375.0, 825.0], "params": [1]},
        # Rotate's 8 lists: (0, 1) .. (0, 4), (1, 1) .. (1, 4); choice 6 is (1, 3).
        (1, 0, 99, 6): {"type": "Rotate", "coord": [5.0, 995.0], "params": [1, 3]},
        # Push has 5 lists: choice 8 is 8 mod 5 = 3 (right).
        (2, 48, 9, 8): {"type": "Push", "coord": [485.0, 95.0], "params": [3]},
        (4, 0, 0, 8): {"type": "Grasp", "coord": [5.0, 5.0], "params": [0]},  # 8 mod 2
        # Switch_view carries its point (an active unlock of the dashboard needs one).
        (5, 10, 20, 6): {"type": "Switch_view", "coord": [105.0, 205.0], "params": ["dashboard"]},
        (6, 3, 4, 8): {"type": "Timed_wait", "coord": None, "params": []},
    }
    for action, want in decoded.items():
        assert env.structured_action(np.array(action)) == want
    assert CHOICES == len(PARAMETERS["Switch_view"]) == 9
    assert {name: len(lists) for name, lists in PARAMETERS.items()} == {
        "Press": 3, "Rotate": 8, "Push": 5, "Pull": 5, "Grasp": 2, "Switch_view": 9,
        "Timed_wait": 1,
    }  # fmt: skip
    coarse = _rl(sample.bench, grid=3)
    assert coarse.action_space.nvec.tolist() == [7, 3, 3, 9]
    assert coarse.structured_action([0, 1, 2, 0])["coord"] == [500.0, 5000 / 6]
    for bad in ([0, 1, 2], [7, 0, 0, 0], [0, 3, 0, 0], [0, 0, 0, -1], [0.5, 0, 0, 0]):
        with pytest.raises(replay.ActionError, match="DeviceRL action"):
            coarse.structured_action(bad)
    with pytest.raises(replay.ConfigError, match="grid"):
        _rl(sample.bench, grid=0)


def test_a_hand_worked_episode_played_with_integers(sample: Sample) -> None:
    """hw_kettle_c (λ 2; geometry in tests/data/hand_worked/kettle_c_parse_multigoal_chain.json):
    from the right view, the lid release button (x 427.5..534.4, y 73.0..110.0) holds cell
    (48, 9) = (485, 95), the power button (x 412.2..584.0, y 821.2..876.6) cell (50, 85) =
    (505, 855). Open the lid (goal 1), close it, switch on, wait: the wait boils the water and
    the immediate chain returns to standby, completing goals 2 and 3 in one step."""
    plays = [
        ([PUSH, 48, 9, 1], "transition", "LidOpen", 1.0),
        ([PUSH, 48, 9, 0], "transition", "Standby", 0.0),
        ([PUSH, 50, 85, 1], "transition", "Boiling", 0.0),
        ([TIMED_WAIT, 0, 0, 0], "transition", "Standby", 2.0),
    ]
    rl = _rl(sample.bench)
    text = replay.env.DeviceEnv(sample.bench, image_source=no_images, **SIZE)
    obs, info = rl.reset(options={"episode_id": "hw_kettle_c-c1"})
    text.reset(options={"episode_id": "hw_kettle_c-c1"})
    assert info["c_opt"] == [1, 3, 0] and info["lambda"] == 2.0
    assert obs["budgets"].tolist() == [8.0, 2.0]  # B_global = 2 · 4, B_local = 2 · 1
    assert obs["goal"].tolist() == [1, 0, 0, 0] and obs["view"].argmax() == 3  # right
    for i, (action, kind, state, reward) in enumerate(plays):
        obs, r, terminated, truncated, info = rl.step(np.array(action))
        assert (info["feedback_kind"], info["state_after"], r) == (kind, state, reward)
        assert (terminated, truncated) == (i == 3, False)
        # The text environment, given the call the integers stand for, steps alike.
        point = (info["x"], info["y"]) if "x" in info else None
        call = replay.Action(info["action_type"], point, tuple(info["params"]))
        twin = text.step(f"Action: {call.to_text()}")
        assert twin[1:4] == (r, terminated, truncated)
        assert {k: v for k, v in twin[4].items() if k not in ("output", "action_raw")} == {
            k: v for k, v in info.items() if k != "action_raw"
        }
    assert obs["goal"].tolist() == [0, 0, 0, 1]
    assert obs["budgets"].tolist() == [4.0, 3.0]  # 4 steps of 8; B_local refilled to 2 · 3
    assert rl.session.finish().episode.spl == 1.0


def test_sampled_actions_always_parse_and_step_like_device_v0() -> None:
    """200 sampled actions on the bundled benchmark: every one is well formed (no parse
    failure, no missing or out-of-range point); what is refused is refused by the device
    (a view it lacks, an axonometric view, the locked dashboard). Played as structured
    actions by `vge/Device-v0`, they give the same rewards, endings and infos."""
    rl = _rl(LOGS_BENCH)
    text = replay.env.DeviceEnv(LOGS_BENCH, image_source=no_images, **SIZE)
    rl.action_space.seed(0)
    rl.reset(seed=0)
    text.reset(seed=0)
    kinds: Counter[str] = Counter()
    invalid: Counter[str] = Counter()
    types: Counter[str] = Counter()
    for _ in range(200):
        action = rl.action_space.sample()
        structured = rl.structured_action(action)
        got = rl.step(action)
        assert text.step(structured)[1:] == got[1:]
        info = got[4]
        assert info["parse_ok"] and "parse_detail" not in info
        kinds[info["feedback_kind"]] += 1
        types[structured["type"]] += 1
        if info["feedback_kind"] == "invalid_action":
            invalid[info["error_detail"]] += 1
        assert log_step_of(structured).action is not None
        if got[2] or got[3]:
            rl.reset()
            text.reset(options={"episode_id": rl.session.task.episode_id})
    assert sum(kinds.values()) == 200 and len(types) == 7
    assert set(invalid) <= {"invalid_view", "axonometric_view", "locked_dashboard"}
    assert kinds["transition"] + kinds["view_switched"] > 0


def test_the_parameter_table_and_the_grid_reach_every_transition_of_the_bundled_benchmark() -> None:
    """Each interaction transition of `logs/bench` accepts some parameter list of the table,
    and each of its boxes (and each dashboard region) holds a point of the default grid."""
    bench = replay.Benchmark.open(LOGS_BENCH)
    centres = [cell_centre(i, 100) for i in range(100)]

    def holds_a_point(rect: tuple) -> bool:
        x0, y0, x1, y1 = rect[:4]
        return any(x0 <= c <= x1 for c in centres) and any(y0 <= c <= y1 for c in centres)

    transitions = 0
    for device_id in sorted(bench.ssm_paths):
        machine = bench.machine(device_id)
        for entries in machine.by_state_view.values():
            for tr, rects in entries:
                lists = PARAMETERS[DISPLAY_NAMES[tr.action]]
                assert any(tr.params_match(normalize_params(list(p))) for p in lists), tr
                assert all(holds_a_point(r) for r in rects), (device_id, tr.component)
                transitions += 1
        assert all(holds_a_point(r) for rs in machine.dashboard_regions.values() for r in rs)
    assert transitions > 1000


FLATTEN = """
import json, sys
import gymnasium
from gymnasium.wrappers import FilterObservation, FlattenObservation
import replay.env

bench = sys.argv[1]
rl = FlattenObservation(gymnasium.make("vge/DeviceRL-v0", bench=bench, image_width=32, image_height=24))
obs, _ = rl.reset(seed=0)
rl.action_space.seed(0)
for _ in range(20):
    obs, _, terminated, truncated, _ = rl.step(rl.action_space.sample())
    if terminated or truncated:
        obs, _ = rl.reset()
text = gymnasium.make("vge/Device-v0", bench=bench, image_width=32, image_height=24)
numbers = FlattenObservation(FilterObservation(text, ["step", "goal_index", "n_goals"]))
print(json.dumps({"rl": rl.observation_space.shape[0], "obs": obs.shape[0],
                  "dtype": str(obs.dtype), "numbers": numbers.observation_space.shape[0]}))
"""


def test_flatten_observation_is_small_and_its_size_comes_from_the_benchmark() -> None:
    """Under a 3 GiB address-space bound (the 2**31-wide one-hots took 2 GiB each): the
    flattened observation is the image and 2 budgets, 1 dashboard flag, a one-hot of the goal
    index (the most goals, 4, plus one) and of the 9 views."""
    tasks = [json.loads(line) for line in (LOGS_BENCH / "tasks.jsonl").read_text().splitlines()]
    goals = max(len(t["goals"]) for t in tasks)
    steps = 5 * max(sum(t["c_opt"]) for t in tasks)  # λ 5, the largest L_opt
    assert (goals, steps) == (4, 60)
    done = run_bounded([sys.executable, "-c", FLATTEN, str(LOGS_BENCH)], timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    sizes = json.loads(done.stdout_head)
    assert sizes == {
        "rl": 24 * 32 * 3 + 2 + 1 + (goals + 1) + 9,
        "obs": 2321,
        "dtype": "float32",
        "numbers": (steps + 1) + (goals + 1) + goals,
    }
    assert sizes["rl"] == 2321 and sizes["numbers"] == 70
    assert done.peak_memory < 400 * 1024**2


@pytest.mark.parametrize("mode", ["sync", "async"])
def test_a_vector_env_of_two(sample: Sample, mode: str) -> None:
    envs = gymnasium.make_vec(
        RL_ENV_ID, num_envs=2, vectorization_mode=mode, bench=str(sample.bench), **SIZE
    )
    singles = [gymnasium.make(RL_ENV_ID, bench=str(sample.bench), **SIZE) for _ in range(2)]
    try:
        envs.action_space.seed(3)
        batch, _ = envs.reset(seed=5)
        for i, env in enumerate(singles):
            env.reset(seed=5 + i)
        for _ in range(3):
            actions = envs.action_space.sample()
            batch, rewards, terminated, truncated, infos = envs.step(actions)
            for i, env in enumerate(singles):
                obs, reward, *ends, info = env.step(actions[i])
                assert rewards[i] == reward and [terminated[i], truncated[i]] == ends
                assert all(np.array_equal(batch[k][i], obs[k]) for k in obs)
                assert infos["feedback_kind"][i] == info["feedback_kind"]
        assert envs.observation_space.contains(batch)
        assert batch["image"].shape == (2, 24, 32, 3)
    finally:
        envs.close()
