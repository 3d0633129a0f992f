"""`vge export --format atif`: the hand-worked runs as ATIF trajectories, validated by the
`atif` package's `Trajectory`: one file per episode, an agent step per step, observations
with the feedback and the pictures, the replay's verdicts in `extra`, per-step usage when
the steps table has it, the same bytes twice."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from atif import Trajectory
from inspect_ai.log import read_eval_log_sample
from PIL import Image

import vge_analytics as va
from vge_analytics.export import export

from ..conftest import HAND


def _load(path: Path) -> Trajectory:
    return Trajectory.model_validate_json(path.read_text())


def _agent_steps(traj: Trajectory) -> list:
    return [s for s in traj.steps if s.source == "agent"]


def test_one_valid_trajectory_per_episode(hand_out, hand_atif):
    dest, summary = hand_atif
    assert (summary.runs, summary.files, summary.episodes, summary.steps) == (2, 12, 12, 77)
    table = va.episodes(hand_out).to_dicts()
    for row in table:
        traj = _load(dest / row["run_id"] / f"{row['episode_id']}.json")
        assert traj.schema_version == "ATIF-v1.6"
        assert traj.session_id == f"{row['run_id']}/{row['episode_id']}"
        assert len(_agent_steps(traj)) == row["n_steps"]
        assert [s.source for s in traj.steps[:2]] == ["system", "user"]
        assert [s.step_id for s in traj.steps] == list(range(1, len(traj.steps) + 1))
        for key in ("success", "spl", "state_f1", "goals_completed", "termination", "L_opt"):
            assert traj.extra[key] == row[key]
        assert traj.final_metrics.total_steps == row["n_steps"]
    assert len(table) == 12


def test_hand_checked_trajectory(hand_out, hand_atif):
    """kettle_c (tests/data/hand_worked/kettle_c_parse_multigoal_chain.json): eight steps,
    a parse failure first (no tool call), then a push that opens the lid."""
    dest, _ = hand_atif
    case = json.loads((HAND / "kettle_c_parse_multigoal_chain.json").read_text())
    traj = _load(dest / "kettle-vlm" / "hw_kettle_c.json")
    agent = _agent_steps(traj)
    assert len(agent) == 8
    assert agent[0].message == case["episode"]["steps"][0]["output"]
    assert agent[0].tool_calls is None
    assert agent[0].extra["parse_detail"] == "unknown_action"
    assert agent[0].observation.results[0].source_call_id is None
    (call,) = agent[1].tool_calls
    assert (call.function_name, call.arguments) == (
        "push",
        {"params": ["1"], "coord": [480.0, 90.0]},
    )
    (result,) = agent[1].observation.results
    assert result.source_call_id == call.tool_call_id
    assert result.extra["feedback_kind"] == "transition"
    steps = va.episode_steps(hand_out, "kettle-vlm", "hw_kettle_c")
    for step, feedback in zip(agent, steps["feedback_text"].to_list(), strict=True):
        text = step.observation.results[0].content[0].text
        assert f"What happened: {feedback}" in text
    assert traj.extra["instructions"] == [
        "Open the lid.",
        "Close it and boil the water.",
        "Let the kettle return to standby.",
    ]
    assert traj.extra["spl"] == case["expected"]["episode"]["spl"] == 0.5
    assert traj.extra["error_types"] == {"action_error": 3, "invalid_coord": 1}
    assert [s.timestamp for s in agent] == [None] * 8  # the hand-worked logs record no time


def test_steps_after_the_end_have_no_observation(hand_atif):
    dest, _ = hand_atif
    agent = _agent_steps(_load(dest / "kettle-vlm" / "hw_kettle_b.json"))
    assert [s.observation is None for s in agent] == [False] * 6 + [True] * 2
    assert [s.extra["truncated"] for s in agent] == [False] * 6 + [True] * 2


def test_pictures_written_once_and_named_relative(hand_atif):
    dest, _ = hand_atif
    run = dest / "kettle-vlm"
    names = set()
    for path in run.glob("*.json"):
        traj = _load(path)
        user = traj.steps[1].message
        parts = [user] + [
            s.observation.results[0].content for s in _agent_steps(traj) if s.observation
        ]
        for content in parts:
            text, image = content
            assert text.type == "text" and image.type == "image"
            assert image.source.media_type == "image/jpeg"
            names.add(image.source.path)
    assert names and all(n.startswith("images/") for n in names)
    assert sorted(p.name for p in (run / "images").iterdir()) == sorted(n[7:] for n in names)
    for name in names:
        with Image.open(run / name) as picture:
            assert picture.format == "JPEG" and max(picture.size) == 512
    # the oven's benchmark has no pictures: text alone, no folder
    oven = _load(dest / "oven-human" / "hw_dash_a.json")
    assert isinstance(oven.steps[1].message, str)
    assert not (dest / "oven-human" / "images").exists()


def test_the_same_bytes_twice(hand_out, hand_atif, tmp_path):
    dest, _ = hand_atif
    export(hand_out, "atif", tmp_path, images="embed")
    first = sorted(p.relative_to(dest) for p in dest.rglob("*") if p.is_file())
    second = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*") if p.is_file())
    assert first == second and len(first) == 12 + 5
    for rel in first:
        assert (dest / rel).read_bytes() == (tmp_path / rel).read_bytes()


def test_usage_per_step_when_recorded(out_with_usage, tmp_path):
    export(out_with_usage, "atif", tmp_path / "atif", images="none")
    agent = _agent_steps(_load(tmp_path / "atif" / "kettle-vlm" / "hw_kettle_b.json"))
    for step in agent[:6]:
        assert step.metrics.prompt_tokens == 1000
        assert step.metrics.completion_tokens == 50
        assert step.metrics.cost_usd == 0.002
        assert step.metrics.extra == {"latency_s": 1.25}
    assert [s.metrics for s in agent[6:]] == [None, None]
    final = _load(tmp_path / "atif" / "kettle-vlm" / "hw_kettle_b.json").final_metrics
    assert (final.total_prompt_tokens, final.total_completion_tokens) == (6000, 300)
    assert final.total_cost_usd == pytest.approx(0.012)
    assert final.extra == {"total_latency_s": 7.5}
    oven = _agent_steps(_load(tmp_path / "atif" / "oven-human" / "hw_dash_a.json"))
    assert all(s.metrics is None for s in oven)

    export(out_with_usage, "inspect", tmp_path / "inspect", images="none", runs=["kettle-vlm"])
    sample = read_eval_log_sample(tmp_path / "inspect" / "kettle-vlm.eval", "hw_kettle_b")
    usage = sample.model_usage["model-k"]
    assert (usage.input_tokens, usage.output_tokens, usage.total_tokens) == (6000, 300, 6300)
    assert usage.total_cost == pytest.approx(0.012)
    answers = [m for m in sample.messages if m.role == "assistant"]
    assert answers[0].metadata["latency_s"] == 1.25
    assert "prompt_tokens" not in answers[-1].metadata
