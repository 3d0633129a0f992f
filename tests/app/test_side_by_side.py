"""The Side by side page's functions (`vge_analytics.dashboard`) on the hand-worked pair of
`vge diff` (tests/vge_analytics/reports/diff_pair.py: the kettle_c task).

The optimal next steps, worked out by hand from the kettle's notes (tests/data/hand_worked/
kettle_c_parse_multigoal_chain.json; goals LidOpen, BoilingComplete, Standby; PROTOCOL §4.3
tie-breaks):
- (Standby, right), goal LidOpen: lid push[1], in view right (its right box x 427.48..534.35,
  y 73.05..109.99): no switch.
- (LidOpen, right), goal BoilingComplete: lid push[0] and power push[1] (through Error) both
  lower the distance, in view right, without a switch; lid push[0] stays safe (rule 1).
- (Standby, right), goal BoilingComplete: power push[1] (right box x 412.21..583.97,
  y 821.16..876.57).
- (Boiling, right): the wait.
- (LidOpen, front): lid push[0] in view front (box x 728.70..825.48, y 59.17..84.00).
- (LidOpen, bottom): the lid has no bottom box; power push[1] has one. Through the lid the
  plan costs (3 transitions, 1 switch), through power and Error (3, 0): the dangerous
  shortcut is cheaper, so it is the optimal next step (rule 1 only breaks ties).
- (Standby, front_top), the axonometric view: no interaction there, so a switch to front
  (the first interactable view in the order of rule 3 holding the lid).
"""

from __future__ import annotations

import io
from pathlib import Path

import polars as pl
import pytest
from PIL import Image

import vge_analytics as va
from vge_analytics import dashboard as dash

from ..vge_analytics.reports.diff_pair import build_hand_pair

LID_RIGHT = (427.480916, 73.047859, 534.351145, 109.991604)
POWER_RIGHT = (412.213740, 821.158690, 583.969466, 876.574307)
LID_FRONT = (728.701406, 59.167275, 825.475600, 84.002922)
POWER_BOTTOM = (765.690377, 410.792952, 899.581590, 559.471366)
GOALS = ["LidOpen", "BoilingComplete", "Standby"]


@pytest.fixture(scope="module")
def pair(tmp_path_factory) -> Path:
    return build_hand_pair(tmp_path_factory.mktemp("side"))


def situation(state: str, view: str, goal_index: int) -> pl.DataFrame:
    """One step, as the steps table has it, whose situation before is (state, view)."""
    return pl.DataFrame(
        {
            "state_before": [state],
            "view_before": [view],
            "goal_index": [goal_index],
            "dashboard_unlocked": [None],
        }
    )


def box_of(optimal: dash.OptimalStep) -> tuple[float, ...]:
    assert len(optimal.boxes) == 1 and optimal.boxes[0].role == "optimal"
    b = optimal.boxes[0]
    return (b.x0, b.y0, b.x1, b.y1)


def test_optimal_next_steps_by_hand(pair: Path) -> None:
    machine = dash.device_machine(pair, "kettle", "A")
    full = va.episode_steps(pair, "A", "same")

    def at(step: int) -> dash.OptimalStep:
        optimal = dash.optimal_next_step(machine, full, GOALS, step)
        assert optimal is not None
        return optimal

    first = at(0)  # (Standby, right), goal LidOpen
    assert first.component == "lid_release_button" and first.action.startswith("Push(")
    assert first.action.endswith("params=[1])") and box_of(first) == pytest.approx(LID_RIGHT)
    second = at(2)  # (LidOpen, right), goal BoilingComplete: the safe lid, not power
    assert second.component == "lid_release_button" and second.action.endswith("params=[0])")
    power = at(6)  # (Standby, right) after closing the lid
    assert power.component == "power_button" and box_of(power) == pytest.approx(POWER_RIGHT)
    wait = at(7)  # Boiling
    assert (wait.action, wait.component, wait.boxes) == ("Timed_wait()", None, ())

    front = dash.optimal_next_step(machine, situation("LidOpen", "front", 1), GOALS, 0)
    assert front is not None and front.component == "lid_release_button"
    assert box_of(front) == pytest.approx(LID_FRONT)
    bottom = dash.optimal_next_step(machine, situation("LidOpen", "bottom", 1), GOALS, 0)
    assert bottom is not None and bottom.component == "power_button"
    assert bottom.action.endswith("params=[1])") and box_of(bottom) == pytest.approx(POWER_BOTTOM)
    axonometric = dash.optimal_next_step(machine, situation("Standby", "front_top", 0), GOALS, 0)
    assert axonometric == dash.OptimalStep("Switch_view(params=[front])", None, ())
    # Past the last goal there is nothing to plan.
    assert dash.optimal_next_step(machine, situation("Standby", "right", 3), GOALS, 0) is None


def test_pair_rows_labels_and_default(pair: Path) -> None:
    rows = dash.pair_rows(pair, "A", "B")
    assert rows.columns[:2] == ["episode_id", "device_id"]
    assert rows.drop("device_id").equals(va.diff(pair, "A", "B").episodes)
    labels = dash.pair_labels(rows)
    assert labels["prefix"] == "prefix · kettle · A solved · B failed · part at step 2"
    assert labels["same"] == "same · kettle · A solved · B solved · identical"
    # Sorted: clean, late, longer, ...; longer is the first that only one run solved.
    assert dash.default_episode(rows) == "longer"
    assert dash.default_episode(rows.filter(pl.col("success_a") == pl.col("success_b"))) == "clean"


def test_marks_and_summary(pair: Path) -> None:
    rows = {r["episode_id"]: r for r in dash.pair_rows(pair, "A", "B").iter_rows(named=True)}
    late = dash.step_marks(rows["late"])
    assert late == {1: ["first difference", "B's first error"]}
    assert [dash.step_label(k, late) for k in range(3)] == [
        "0",
        "1 · first difference · B's first error",
        "2",
    ]
    assert dash.step_marks(rows["clean"]) == {0: ["first difference", "A's first error"]}
    assert dash.step_marks(rows["same"]) == {0: ["A's first error", "B's first error"]}
    assert dash.pair_summary(rows["same"]) == (
        "**First difference** none: identical replays · **A's first error** step 0 · "
        "**B's first error** step 0 · steps A 8, B 8"
    )


def test_side_picture_draws_the_optimal_box_and_the_click(pair: Path) -> None:
    got = dash.side_picture(pair, "B", "late", 1)  # B clicks at x 1200 (off the view)
    assert got.optimal is not None and got.optimal.component == "lid_release_button"
    img = Image.open(io.BytesIO(got.png)).convert("RGB")
    sx, sy = img.width / 1000, img.height / 1000  # the view, scaled to 720 pixels wide
    x0, y0, y1 = LID_RIGHT[0] * sx, LID_RIGHT[1] * sy, LID_RIGHT[3] * sy  # lid push[0]'s box
    left_edge = (round(x0) + 1, round((y0 + y1) / 2))
    assert img.getpixel(left_edge) == dash.ROLE_COLORS["optimal"]
    step0 = dash.side_picture(pair, "B", "late", 0)  # a click inside the lid box
    img0 = Image.open(io.BytesIO(step0.png)).convert("RGB")
    assert img0.getpixel((round(480 * sx), round(90 * sy))) == dash.CLICK_COLOR
    row = va.episode_steps(pair, "B", "late").row(1, named=True)
    assert dash.side_caption(row, got.optimal) == (
        "view right · Push(coord=[1200, 90], params=[0]) → invalid_coord · "
        f"optimal (blue): {got.optimal.action} on lid_release_button"
    )
    with pytest.raises(va.UnknownRunError, match="no replayed step 5 in episode 'late' of 'A'"):
        dash.side_picture(pair, "A", "late", 5)


def test_the_heading_past_the_end_of_a_log() -> None:
    # B's log holds 2 steps (0 and 1); the shared slider follows A's longer log.
    assert dash.side_heading("A", "a", 1, 5) == "**A · a** · step 1 of steps 0–4"
    assert dash.side_heading("B", "b", 1, 2) == "**B · b** · step 1 of steps 0–1"
    assert dash.side_heading("B", "b", 2, 2) == "**B · b** · its log ended at step 1"
    assert dash.side_heading("B", "b", 4, 1) == "**B · b** · its log ended at step 0"
    assert dash.side_heading("B", "b", 0, 1) == "**B · b** · step 0, its only step"
    assert dash.side_heading("B", "b", 0, 0) == "**B · b** · its log has no step"
    assert dash.ended_note("B", 1, 2) is None
    assert dash.ended_note("B", 2, 2) == (
        "B's log ended at step 1: no step 2 to show (the slider follows the longer log)."
    )
    assert dash.ended_note("B", 0, 0) == "B's log of this episode has no step."
    # Past the end of a log, never the old "step 2 of 1" (a step beyond the steps).
    for n in range(4):
        for step in range(n, n + 3):
            assert "ended" in dash.side_heading("B", "b", step, n) or n == 0
