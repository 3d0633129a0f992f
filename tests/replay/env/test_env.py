"""`vge/Device-v0`: Gymnasium's checker, the optimal plan of every hand-worked task played
through `gymnasium.make`, seeded determinism, text and structured actions, and the live rows
equal to the replay of the log the episode leaves."""

from __future__ import annotations

import warnings

import gymnasium
import numpy as np
import pytest
from gymnasium.error import ResetNeeded
from gymnasium.utils.env_checker import check_env

import replay
from replay.env import ENV_ID, STEP_FIELDS, DeviceEnv, log_step_of, no_images
from replay.env._images import CANVAS

from ..conftest import IMAGE_SIZE, Sample, _cases_cache

SIZE = {"image_width": 40, "image_height": 30}
DISPLAY = {"press": "Press", "rotate": "Rotate", "push": "Push", "pull": "Pull"}
DISPLAY |= {"grasp": "Grasp", "switch_view": "Switch_view", "timed_wait": "Timed_wait"}


def _make(sample: Sample, **kwargs) -> gymnasium.Env:
    return gymnasium.make(ENV_ID, bench=str(sample.bench), **(SIZE | kwargs))


def _hand_worked_ids() -> list[str]:
    """Copy 1 of every case (copy 0 of the first has an odd id; both work)."""
    return [f"{doc['task']['episode_id']}-c1" for doc in _cases_cache]


def _structured(action: replay.Action) -> dict:
    return {
        "type": DISPLAY[action.type],
        "coord": list(action.coord) if action.coord is not None else None,
        "params": list(action.params),
    }


def test_passes_gymnasiums_checker(sample: Sample) -> None:
    env = _make(sample)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped)
    assert [str(w.message) for w in caught] == []
    env.close()


@pytest.mark.parametrize("episode_id", _hand_worked_ids())
def test_the_optimal_plan_completes_every_goal_in_exactly_c_opt_steps(
    sample: Sample, episode_id: str
) -> None:
    env = _make(sample)
    obs, info = env.reset(options={"episode_id": episode_id})
    task = env.unwrapped.session.task
    plan = replay.semantics.setup_episode(env.unwrapped.machine, task).plan
    assert info["c_opt"] == list(plan.c_opt)
    assert obs["step"] == 0 and obs["goal_index"] == 0 and obs["feedback"] == ""
    reward = 0.0
    for i, planned in enumerate(plan.steps):
        assert obs["goal_index"] == planned.goal_index
        assert obs["instruction"] == (task.instructions + [""] * 9)[planned.goal_index]
        # Text and structured actions alternate: both are the same step.
        action = (
            f"Thinking: step {i}\nAction: {planned.action.to_text()}"
            if i % 2 == 0
            else _structured(planned.action)
        )
        obs, r, terminated, truncated, info = env.step(action)
        reward += r
        last = i == len(plan.steps) - 1
        assert (terminated, truncated) == (last, False), (i, info["feedback_text"])
        assert info["step"] == i and obs["step"] == i + 1
        assert info["feedback_kind"] != "invalid_action"
    assert len(plan.steps) == sum(plan.c_opt)
    assert reward == len(task.goals) == obs["goal_index"] == obs["n_goals"]
    assert obs["instruction"] == ""
    result = env.unwrapped.session.finish()
    assert result.episode.success and result.episode.spl == 1.0
    with pytest.raises(ResetNeeded):
        env.step("Action: Timed_wait()")


def _play(env: gymnasium.Env, seed: int, actions: list) -> list:
    obs, info = env.reset(seed=seed)
    out = [(obs, info)]
    for action in actions:
        obs, r, terminated, truncated, info = env.step(action)
        out.append((obs, r, terminated, truncated, info))
        if terminated or truncated:
            break
    return out


ACTIONS = [
    "Action: Press(coord=[500, 500], params=[0])",
    {"type": "Switch_view", "params": ["back"]},
    "no action at all",
    "Action: Timed_wait()",
    {"type": "Pull", "coord": [10.5, 990], "params": [4]},
]


def test_the_same_seed_gives_the_same_episode(sample: Sample) -> None:
    first = _play(_make(sample), 11, ACTIONS)
    second = _play(_make(sample), 11, ACTIONS)
    assert len(first) == len(second)
    for a, b in zip(first, second, strict=True):
        for x, y in zip(a, b, strict=True):
            if isinstance(x, dict):
                assert x.keys() == y.keys()
                for key in x:
                    assert np.array_equal(x[key], y[key]) if key == "image" else x[key] == y[key]
            else:
                assert x == y
    env = _make(sample)
    picked = {env.reset(seed=s)[0]["episode_id"] for s in range(12)}
    assert len(picked) > 3
    # Tasks that cannot be played (an unknown device, an unknown goal) are never picked.
    assert not picked & {"ghost-device", "bad-task"}


def test_a_text_and_a_structured_action_are_the_same_step(sample: Sample) -> None:
    env = _make(sample)
    episode_id = _hand_worked_ids()[0]
    obs, _ = env.reset(options={"episode_id": episode_id})
    other = next(v for v in obs["views"] if v not in (obs["view"], "dashboard"))
    rows = []
    for action in (
        f"Thinking: the other side.\nAction: Switch_view(params=[{other}])",
        {"type": "Switch_view", "coord": None, "params": [other]},
    ):
        env.reset(options={"episode_id": episode_id})
        rows.append(env.step(action)[4])
    text, structured = rows
    # A null column is not in `info`: a structured action has no output and no thinking.
    assert text["output"] is not None and "output" not in structured
    assert text["thinking"] == "the other side." and "thinking" not in structured
    different = {"output", "thinking", "action_raw"}
    assert {k: v for k, v in text.items() if k not in different} == {
        k: v for k, v in structured.items() if k not in different
    }
    assert text["feedback_kind"] == "view_switched" and text["view_after"] == other


def test_a_live_episode_and_the_replay_of_its_log_give_the_same_rows(sample: Sample) -> None:
    env = DeviceEnv(sample.bench, image_source=no_images, **SIZE)
    obs, _ = env.reset(seed=3)
    infos, steps = [], []
    for action in ACTIONS * 3:
        obs, _, terminated, truncated, info = env.step(action)
        infos.append(info)
        steps.append(log_step_of(action))
        if terminated or truncated:
            break
    session = env.session
    log = replay.EpisodeLog(episode_id=obs["episode_id"], steps=steps)
    replayed = replay.replay_episode(
        session.machine, session.task, log, lam=session.budget.lam, run_id="live", model="live",
        agent_kind="vlm",
    )  # fmt: skip
    # `info` is the row without its null columns.
    assert [dict(zip(STEP_FIELDS, t, strict=True)) for t in replayed.step_tuples] == [
        {key: info.get(key) for key in STEP_FIELDS} for info in infos
    ]
    assert all(None not in info.values() for info in infos)
    assert replayed.episode == session.finish().episode


def test_the_image_is_the_current_view_at_the_environments_size(sample: Sample) -> None:
    """The kettle's views are 64 x 48 plain colours (tests/replay/conftest.py); other devices
    have no image and show the plain canvas."""
    assert (SIZE["image_width"], SIZE["image_height"]) != IMAGE_SIZE
    env = _make(sample, render_mode="rgb_array")
    kettle = next(i for i in _hand_worked_ids() if i.startswith("hw_kettle"))
    obs, _ = env.reset(options={"episode_id": kettle})
    assert obs["image"].shape == (30, 40, 3) and obs["image"].dtype == np.uint8
    order = ["front", "back", "left", "right", "top", "bottom", "front_top", "back_bottom"]
    assert tuple(obs["image"][15, 20]) == (30 * order.index(obs["view"]), 100, 200)
    other = next(v for v in order if v != obs["view"])
    obs = env.step({"type": "Switch_view", "params": [other]})[0]
    assert tuple(obs["image"][15, 20]) == (30 * order.index(other), 100, 200)
    assert np.array_equal(env.render(), obs["image"])
    dashboard = next(i for i in _hand_worked_ids() if i.startswith("hw_dash"))
    obs, _ = env.reset(options={"episode_id": dashboard})
    assert tuple(obs["image"][-1, -1]) == CANVAS


def test_misuse_is_refused_with_one_line(sample: Sample) -> None:
    env = DeviceEnv(sample.bench, image_source=no_images, **SIZE)
    with pytest.raises(ResetNeeded):
        env.step("Action: Timed_wait()")
    with pytest.raises(replay.ConfigError, match="not in"):
        env.reset(options={"episode_id": "no-such-episode"})
    with pytest.raises(replay.ConfigError, match="unknown reset option"):
        env.reset(options={"episode": "x"})
    with pytest.raises(replay.TaskError):
        env.reset(options={"episode_id": "bad-task"})
    env.reset(seed=0)
    with pytest.raises(replay.ActionError, match="structured action") as err:
        env.step({"type": "Press", "coord": "middle"})
    assert "\n" not in str(err.value)
    with pytest.raises(replay.ActionError):
        env.step(42)  # type: ignore[arg-type]
