"""`vge export --format inspect`: the hand-worked runs as Inspect logs, read back with
`inspect_ai.log`: one log per run, one sample per episode, the conversation, the replay's
verdicts as scores, the run's metrics as results, the pictures, the same bytes twice."""

from __future__ import annotations

import base64
import io
import json
import zipfile

import pytest
from inspect_ai.log import read_eval_log, read_eval_log_sample
from inspect_ai.model import ContentImage
from PIL import Image

import vge_analytics as va
from vge_analytics.export import export

from ..conftest import HAND, KETTLE_CASES, OVEN_CASES


def _case(name: str) -> dict:
    return json.loads((HAND / f"{name}.json").read_text())


def _ids(cases) -> list[str]:
    return sorted(_case(n)["task"]["episode_id"] for n in cases)


def test_one_log_per_run_one_sample_per_episode(hand_inspect):
    dest, summary = hand_inspect
    assert sorted(p.name for p in dest.iterdir()) == ["kettle-vlm.eval", "oven-human.eval"]
    assert (summary.runs, summary.files, summary.episodes, summary.steps) == (2, 2, 12, 77)
    kettle = read_eval_log(dest / "kettle-vlm.eval")
    oven = read_eval_log(dest / "oven-human.eval")
    assert kettle.status == oven.status == "success"
    assert [s.id for s in kettle.samples] == _ids(KETTLE_CASES)
    assert [s.id for s in oven.samples] == _ids(OVEN_CASES)
    assert (kettle.eval.task, kettle.eval.model, oven.eval.model) == (
        "vgebench",
        "model-k",
        "model-o",
    )
    assert kettle.eval.dataset.samples == 7


def test_hand_checked_sample(hand_out, hand_inspect):
    """kettle_c: three goals, eight steps, parse failures among them, success with SPL 0.5
    (tests/data/hand_worked/kettle_c_parse_multigoal_chain.json)."""
    dest, _ = hand_inspect
    case = _case("kettle_c_parse_multigoal_chain")
    sample = read_eval_log_sample(dest / "kettle-vlm.eval", "hw_kettle_c")
    assert (
        sample.input
        == "Open the lid.\nClose it and boil the water.\nLet the kettle return to standby."
    )
    assert sample.target == ["LidOpen", "BoilingComplete", "Standby"]
    assert [m.role for m in sample.messages] == ["system", "user"] + ["assistant", "user"] * 8
    steps = va.episode_steps(hand_out, "kettle-vlm", "hw_kettle_c")
    answers = [m.text for m in sample.messages if m.role == "assistant"]
    logged = case["episode"]["steps"]
    # seven model outputs, then a structured action (shown as the replay wrote it)
    assert answers[:7] == [s["output"] for s in logged[:7]]
    assert "output" not in logged[7]
    assert answers[7] == steps["action_raw"][7] == "Timed_wait()"
    expected = case["expected"]["episode"]
    assert sample.scores["success"].value == 1.0
    assert sample.scores["spl"].value == expected["spl"] == 0.5
    assert sample.scores["state_f1"].value == expected["state_f1"] == 1.0
    assert sample.scores["goals_completed"].value == 3
    assert sample.scores["goals_completed"].answer == "3 of 3"
    assert sample.metadata["termination"] == "success"
    assert sample.metadata["L_act"] == 8
    errors = steps.filter(steps["error_type"].is_not_null())["error_type"].value_counts()
    assert sample.metadata["error_types"] == dict(errors.iter_rows())
    first = sample.messages[2]
    assert first.metadata["parse_ok"] is False
    assert first.metadata["parse_detail"] == "unknown_action"
    assert first.metadata["error_type"] == "action_error"
    # what the agent was told after each step: its feedback, and the next request
    for i, feedback in enumerate(steps["feedback_text"].to_list()):
        assert f"What happened: {feedback}" in sample.messages[3 + 2 * i].text
    assert (
        "Request: Close it and boil the water.\n(part 2 of 3 of the task)"
        in sample.messages[5].text
    )
    assert sample.messages[-1].text.endswith("The episode is over: every goal is reached.")


def test_truncated_steps_are_answers_without_reply(hand_inspect):
    """kettle_b: the global budget ends the episode after six steps; the log holds two more."""
    dest, _ = hand_inspect
    sample = read_eval_log_sample(dest / "kettle-vlm.eval", "hw_kettle_b")
    roles = [m.role for m in sample.messages]
    assert roles == ["system", "user"] + ["assistant", "user"] * 6 + ["assistant"] * 2
    assert [m.metadata["truncated"] for m in sample.messages if m.role == "assistant"] == [
        False
    ] * 6 + [True] * 2
    assert sample.messages[-3].text.endswith(
        "The episode is over: the episode's step budget is spent. "
        "(The log holds 2 more response(s), which the replay does not play.)"
    )
    assert sample.scores["success"].value == 0.0
    assert sample.scores["success"].answer == "budget_global"


def test_scores_equal_the_episodes_table(hand_out, hand_inspect):
    dest, _ = hand_inspect
    table = {r["episode_id"]: r for r in va.episodes(hand_out).to_dicts()}
    seen = 0
    for name in ("kettle-vlm.eval", "oven-human.eval"):
        for sample in read_eval_log(dest / name).samples:
            row = table[sample.id]
            assert sample.scores["success"].value == float(row["success"])
            assert sample.scores["spl"].value == row["spl"]
            assert sample.scores["state_f1"].value == row["state_f1"]
            assert sample.scores["goals_completed"].value == row["goals_completed"]
            assert sample.metadata["n_steps"] == row["n_steps"]
            seen += 1
    assert seen == 12


def test_results_hold_the_runs_metrics(hand_out, hand_inspect):
    dest, _ = hand_inspect
    expected = {r.pop("run_id"): r for r in va.metrics(hand_out, by=("run_id",)).to_dicts()}
    for run_id in ("kettle-vlm", "oven-human"):
        results = read_eval_log(dest / f"{run_id}.eval", header_only=True).results
        (score,) = results.scores
        got = {name: metric.value for name, metric in score.metrics.items()}
        assert got == {k: v for k, v in expected[run_id].items() if v is not None}
        assert results.total_samples == results.completed_samples == score.scored_samples
    sr = read_eval_log(dest / "kettle-vlm.eval", header_only=True).results.scores[0].metrics["SR"]
    assert sr.metadata == {"title": "Success Rate", "direction": "higher", "unit": "percent"}


def test_pictures_beside_what_the_agent_was_shown(hand_inspect):
    """Every user message of a kettle episode shows the view it names, downscaled JPEG; the
    oven's benchmark has no pictures: text alone."""
    dest, _ = hand_inspect
    log = read_eval_log(dest / "kettle-vlm.eval", resolve_attachments=True)
    sample = next(s for s in log.samples if s.id == "hw_kettle_c")
    users = [m for m in sample.messages if m.role == "user"]
    assert len(users) == 9
    for message in users:
        (image,) = [c for c in message.content if isinstance(c, ContentImage)]
        head, data = image.image.split(",", 1)
        assert head == "data:image/jpeg;base64"
        with Image.open(io.BytesIO(base64.b64decode(data))) as picture:
            assert picture.format == "JPEG"
            assert max(picture.size) == 512
    oven = read_eval_log(dest / "oven-human.eval")
    assert all(isinstance(m.content, str) for s in oven.samples for m in s.messages)


def test_no_pictures_with_images_none(hand_out, tmp_path):
    export(
        hand_out, "inspect", tmp_path, runs=["kettle-vlm"], episodes=["hw_kettle_a"], images="none"
    )
    sample = read_eval_log_sample(tmp_path / "kettle-vlm.eval", "hw_kettle_a")
    assert len(sample.messages) == 2 + 2 * 10
    assert all(isinstance(m.content, str) for m in sample.messages)
    assert sample.attachments == {}


def test_selected_episodes_and_their_metrics(hand_out, tmp_path):
    export(hand_out, "inspect", tmp_path, episodes=["hw_kettle_b", "hw_kettle_c"], images="none")
    assert [p.name for p in tmp_path.iterdir()] == ["kettle-vlm.eval"]
    log = read_eval_log(tmp_path / "kettle-vlm.eval")
    assert [s.id for s in log.samples] == ["hw_kettle_b", "hw_kettle_c"]
    # SR over the two exported episodes: one success in two
    assert log.results.scores[0].metrics["SR"].value == pytest.approx(50.0)


def test_the_same_bytes_twice(hand_out, hand_inspect, tmp_path):
    """No clock is read: identifiers come from the ids, times from the recorded steps, and
    the zip members' stamps are fixed."""
    dest, _ = hand_inspect
    export(hand_out, "inspect", tmp_path, images="embed")
    for name in ("kettle-vlm.eval", "oven-human.eval"):
        assert (tmp_path / name).read_bytes() == (dest / name).read_bytes()
        with zipfile.ZipFile(tmp_path / name) as zf:
            assert zf.testzip() is None
            assert {info.date_time for info in zf.infolist()} == {(1980, 1, 1, 0, 0, 0)}
