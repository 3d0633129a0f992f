"""What filters select (store.check_selection), on the two hand-worked runs: kettle-vlm
(model-k, history full) and oven-human (model-o, history 3)."""

from __future__ import annotations

import pytest

import vge_analytics as va
from vge_analytics.store import SelectionCheck, check_selection, describe_filters


def test_values_that_are_there_select_rows(hand_out) -> None:
    assert check_selection(hand_out, None) == SelectionCheck((), False)
    assert check_selection(hand_out, {"model": ["model-k", "model-o"]}) == SelectionCheck(
        (), False
    )
    assert check_selection(hand_out, {"meta_history": "3", "agent_kind": "human"}).line(
        "x"
    ) is None


def test_values_that_are_not_there(hand_out) -> None:
    check = check_selection(hand_out, {"model": "model-q"})
    assert check == SelectionCheck(("no model 'model-q' (nearest: model-k, model-o)",), True)
    assert check.line("--where model=model-q") == (
        "--where model=model-q selects no row: no model 'model-q' (nearest: model-k, model-o)"
    )
    # One value of two: the other selects rows.
    check = check_selection(hand_out, {"model": ["model-k", "model-q"]})
    assert not check.empty and check.line("F") == (
        "F: no model 'model-q' (nearest: model-k, model-o) (the other values select rows)"
    )
    # None stands for null: every run has a model.
    assert check_selection(hand_out, {"model": [None]}).misses == (
        "no model (none) (values: model-k, model-o)",
    )


def test_values_there_that_no_row_has_together(hand_out) -> None:
    check = check_selection(hand_out, {"model": "model-k", "meta_history": "3"})
    assert check == SelectionCheck((), True)
    assert check.line("F") == "F selects no row: each value is there, but no row has them all"


def test_columns_of_steps_and_unknown_columns(hand_out) -> None:
    assert not check_selection(hand_out, {"action_type": "push"}).empty
    check = check_selection(hand_out, {"action_type": "psh", "model": "model-k"})
    assert check.empty and check.misses[0].startswith("no action_type 'psh' (nearest: push")
    with pytest.raises(va.UnknownColumnError, match="unknown filter column 'nosuch'"):
        check_selection(hand_out, {"nosuch": 1})


def test_describe_filters() -> None:
    assert describe_filters({"model": ["a", "b"], "n_goals": 2, "meta_x": [None]}) == (
        "model = a or b, n_goals = 2, meta_x = (none)"
    )


def test_many_values_are_checked_at_once_and_named_in_part(hand_out) -> None:
    wanted = ["model-k", *(f"zz-{k:05d}" for k in range(20_000))]
    check = check_selection(hand_out, {"model": wanted, "n_goals": [1, 2, 3, 99]})
    assert not check.empty
    assert check.misses == (
        *(f"no model 'zz-{k:05d}' (values: model-k, model-o)" for k in range(5)),
        "and 19,995 more model values that no row holds",
        "no n_goals 99 (values: 1, 2, 3)",
    )
