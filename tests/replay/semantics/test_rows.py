"""Step rows built as tuples line up with the StepRow columns and convert to Arrow."""

from __future__ import annotations

from pathlib import Path

import msgspec
import pyarrow as pa

from replay import (
    EpisodeLog,
    StepRow,
    Task,
    arrow_schema,
    load_machine,
    replay_episode,
)
from replay.semantics import rows_to_table

KETTLE = load_machine(Path(__file__).resolve().parents[2] / "data" / "kettle_ssm.json", "kettle")


def _result():
    task = msgspec.convert(
        {"episode_id": "e", "device_id": "kettle", "goals": ["Boiling"], "lambda": 2}, Task
    )
    log = msgspec.convert(
        {
            "episode_id": "e",
            "steps": [
                {
                    "output": "Thinking: try\nAction: Press(coord=[780, 725], params=[1])",
                    "feedback": "operational_error",
                    "state": "Standby",
                    "view": "front",
                    "timestamp": "2026-01-01T00:00:00Z",
                },
                {"action": {"type": "Timed_wait"}, "feedback": "transition"},
                {"output": "Action: Push(coord=[780, 725], params=[1])"},
            ],
        },
        EpisodeLog,
    )
    return replay_episode(KETTLE, task, log, lam=2.0, run_id="r", model="m", agent_kind="vlm")


def test_tuple_rows_match_the_typed_rows_field_by_field() -> None:
    result = _result()
    assert all(len(t) == len(StepRow.__struct_fields__) for t in result.step_tuples)
    first, second, third = result.steps
    # Typed validation of every value against the declared field types.
    for row in result.steps:
        msgspec.convert(msgspec.to_builtins(row), StepRow)
    assert (first.step, first.action_type, first.x, first.y, first.params) == (
        0,
        "press",
        780.0,
        725.0,
        ["1"],
    )
    assert (first.feedback_kind, first.error_type, first.error_detail) == (
        "operational_error",
        "action_error",
        "wrong_action",
    )
    assert (first.is_interaction, first.hit_component, first.hit_target, first.nearest_target) == (
        True,
        True,
        True,
        "power_button",
    )
    assert first.thinking == "try" and first.timestamp == 1767225600.0
    assert first.diverged is False and first.diverged_fields == []
    assert (second.feedback_kind, second.diverged, second.diverged_fields) == (
        "wait_no_effect",
        True,
        ["feedback"],
    )
    # lambda 2, C_opt 1: B_global = B_local = 2; the second step exhausts both (the global
    # one is checked first); the third is truncated.
    assert (second.budget_global_left, second.budget_local_left) == (0.0, 0.0)
    assert third.truncated and third.feedback_kind is None and third.progress is None
    assert result.episode.termination == "budget_global" and result.episode.truncated_steps == 1


def test_rows_convert_to_arrow_with_the_declared_schema() -> None:
    result = _result()
    table = rows_to_table(result.step_tuples, StepRow)
    assert table.schema.equals(arrow_schema(StepRow))
    assert table.num_rows == 3
    assert table.column("params").type == pa.list_(pa.string())
    assert rows_to_table(result.steps, StepRow).equals(table)
    assert rows_to_table([], StepRow).num_rows == 0
