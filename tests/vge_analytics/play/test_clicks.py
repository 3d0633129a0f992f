"""Clicks on the displayed view to the 0..1000 scale, worked by hand (the rounding rule:
`1000 · offset / displayed size`, halves up, within 0..1000), and the actions they make."""

from __future__ import annotations

import pytest

from vge_analytics import play
from vge_analytics._errors import PlayError


@pytest.mark.parametrize(
    ("offset", "displayed", "expected"),
    [
        # The page shows the 768-pixel view 600 pixels wide: 1000 * offset / 600.
        (150, 600, 250),  # 250 exactly
        (300, 600, 500),  # the middle
        (301, 600, 502),  # 501.67 -> 502
        (7, 600, 12),  # 11.67 -> 12
        (0, 600, 0),
        (600, 600, 1000),  # the right edge
        # The same image at its natural width: the middle is still 500.
        (384, 768, 500),
        (100, 768, 130),  # 130.21 -> 130
        # Halves round up (Python's round() would give 2 and 0).
        (1, 400, 3),  # 2.5 -> 3
        (0.4, 800, 1),  # 0.5 -> 1
        (1, 800, 1),  # 1.25 -> 1
        (3, 800, 4),  # 3.75 -> 4
        # A click reported just outside the image stays on the scale.
        (-2, 600, 0),
        (605, 600, 1000),
    ],
)
def test_scale_coordinate_worked_by_hand(offset, displayed, expected) -> None:
    assert play.scale_coordinate(offset, displayed) == expected


def test_click_point_uses_the_displayed_size_not_the_natural_one() -> None:
    # A 768 x 768 view shown at 600 x 600: pixel (150, 450) is (250, 750) on the scale.
    assert play.click_point({"x": 150, "y": 450, "width": 600, "height": 600}) == (250, 750)
    # A view shown 600 x 450 (4:3): each axis is scaled by its own displayed size.
    assert play.click_point({"x": 60, "y": 45, "width": 600, "height": 450}) == (100, 100)
    assert play.click_point({"x": 301, "y": 7, "width": 600, "height": 450}) == (502, 16)
    # 7 / 450 * 1000 = 15.56 -> 16.
    with pytest.raises(PlayError, match="displayed size"):
        play.click_point({"x": 1, "y": 1, "width": 0, "height": 600})
    with pytest.raises(PlayError, match="not a click"):
        play.click_point({"x": 1, "y": 1})
    with pytest.raises(PlayError, match="must be a number"):
        play.click_point({"x": float("nan"), "y": 1, "width": 10, "height": 10})


def test_actions_as_a_human_log_carries_them() -> None:
    assert play.parse_params(" 0 , 3,, ") == ["0", "3"]
    assert play.parse_params("") == []
    assert play.click_action("Rotate", (331, 875), "0, 3", "front") == {
        "type": "Rotate",
        "coord": [331, 875],
        "params": ["0", "3"],
    }
    # A Switch_view with a point (how the locked dashboard is unlocked).
    assert play.click_action("Switch_view", (10, 20), "ignored", "dashboard") == {
        "type": "Switch_view",
        "coord": [10, 20],
        "params": ["dashboard"],
    }
    with pytest.raises(PlayError):
        play.click_action("Timed_wait", (1, 2), "", "front")
    assert play.action_text({"action": play.action("Timed_wait")}) == "Timed_wait(params=[])"
    assert play.click_id(None) is None
    assert play.click_id({"x": 1, "y": 2, "unix_time": 5}) == (5, 1, 2)
