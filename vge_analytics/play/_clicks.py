"""Clicks on a view to the 0..1000 scale, and the structured actions a person's clicks make."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from fractions import Fraction
from typing import Any

import replay
from replay import DASHBOARD, DISPLAY_NAMES, SCALE
from replay.semantics import GRASP, PARAMETER_NAMES, PRESS, PULL, PUSH, ROTATE, codes_text

from .._errors import PlayError

INTERACTIONS = tuple(DISPLAY_NAMES[a] for a in replay.INTERACTIONS)
"""The interactions as a log writes them (`Press`, ...)."""
SWITCH_VIEW = DISPLAY_NAMES[replay.SWITCH_VIEW]
TIMED_WAIT = DISPLAY_NAMES[replay.TIMED_WAIT]
CLICK_ACTIONS = (*INTERACTIONS, SWITCH_VIEW)
"""What a click on the image can do (a `Switch_view` with a point unlocks the dashboard
when the point is on its panel, PROTOCOL §3.2)."""

_DEFAULTS = {PRESS: "0", ROTATE: "0, 1", PUSH: "4", PULL: "4", GRASP: "0"}
"""What the page pre-fills: a short press, a notch clockwise, inwards, outwards, take hold."""
PARAM_HINTS: dict[str, tuple[str, str]] = {
    DISPLAY_NAMES[action]: (
        _DEFAULTS[action],
        f"{PARAMETER_NAMES[action][0]}: {codes_text(action)}"
        + "".join(f"; then {name}, * when it does not matter" for name in PARAMETER_NAMES[action][1:]),
    )
    for action in replay.INTERACTIONS
}
"""Default parameters of each interaction as the page pre-fills them, with what they mean
(the codes of the paper's action space, PROTOCOL §2; the device decides what it accepts)."""


# ----------------------------------------------------------------------- click mapping


def scale_coordinate(offset: float, displayed: float) -> int:
    """A pixel offset along an axis of the displayed image -> that axis of the 0..1000 scale.

    The rule is PROTOCOL §1.2's for boxes, `1000 * offset / displayed`, on the size the image
    is displayed at (never its natural size), rounded to the nearest integer with halves
    rounded up, then kept within 0..1000. Computed in exact fractions, so 0.5 really rounds
    up. A whole number keeps the log readable and loses at most half a unit, less than one
    displayed pixel whenever the image is shown at most 1000 pixels wide.
    """
    if not displayed > 0 or not math.isfinite(displayed):
        raise PlayError(f"the image's displayed size must be positive, not {displayed!r}")
    if not math.isfinite(offset):
        raise PlayError(f"a click's offset must be a number, not {offset!r}")
    value = Fraction(offset) * SCALE / Fraction(displayed)
    return min(max(math.floor(value + Fraction(1, 2)), 0), SCALE)


def click_point(click: Mapping[str, Any]) -> tuple[int, int]:
    """The 0..1000 point of a click as `streamlit-image-coordinates` reports it: `x`, `y`
    (offsets from the image's top-left corner) and `width`, `height` (its displayed size)."""
    try:
        x, y, width, height = (float(click[k]) for k in ("x", "y", "width", "height"))
    except (KeyError, TypeError, ValueError):
        raise PlayError(f"not a click on the image: {dict(click)!r}") from None
    return scale_coordinate(x, width), scale_coordinate(y, height)


def click_id(click: Mapping[str, Any] | None) -> tuple | None:
    """What tells one click from the next (the component reports its last click again on
    every rerun of the page; `PlayState.click` acts on each one once)."""
    if not click:
        return None
    return (click.get("unix_time"), click.get("x"), click.get("y"))


# ----------------------------------------------------------------------------- actions


def parse_params(text: str) -> list[str]:
    """Parameters typed as `a, b`: split on commas, blanks dropped (the engine normalises
    each value, PROTOCOL §1.2)."""
    return [p.strip() for p in text.split(",") if p.strip()]


def action(
    type_: str, coord: Sequence[float] | None = None, params: Sequence[Any] = ()
) -> dict[str, Any]:
    """A structured action as a human log carries it: `{"type", "coord", "params"}`."""
    return {
        "type": type_,
        "coord": None if coord is None else [coord[0], coord[1]],
        "params": list(params),
    }


def click_action(type_: str, point: tuple[int, int], params_text: str, view: str) -> dict:
    """The action a click at `point` carries out: an interaction with the typed parameters,
    or a `Switch_view` to `view` with the point (how the dashboard is unlocked)."""
    if type_ == SWITCH_VIEW:
        return action(SWITCH_VIEW, point, [view])
    if type_ not in INTERACTIONS:
        raise PlayError(f"a click cannot carry out {type_!r}; one of {', '.join(CLICK_ACTIONS)}")
    return action(type_, point, parse_params(params_text))


def action_text(step: Mapping[str, Any]) -> str:
    """How a logged action reads: `Press(coord=[500, 250], params=[0])`."""
    a = step["action"]
    params = ", ".join(str(p) for p in a.get("params") or [])
    coord = a.get("coord")
    inner = (f"coord=[{coord[0]:g}, {coord[1]:g}], " if coord is not None else "") + (
        f"params=[{params}]"
    )
    return f"{a['type']}({inner})"


__all__ = [
    "CLICK_ACTIONS",
    "DASHBOARD",
    "INTERACTIONS",
    "PARAM_HINTS",
    "SCALE",
    "SWITCH_VIEW",
    "TIMED_WAIT",
    "action",
    "action_text",
    "click_action",
    "click_id",
    "click_point",
    "parse_params",
    "scale_coordinate",
]
