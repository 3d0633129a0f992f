"""The fixed vocabulary: the coordinate scale, views, action names and their parameter codes,
feedback kinds, terminations, error types, and the normalisation of parameter values. One
place, so every module agrees (docs/ARCHITECTURE.md, "Where each name lives")."""

from __future__ import annotations

import math

SCALE = 1000
"""The agent's coordinate scale: a point is `[x, y]` with 0..SCALE on both axes of a view,
relative to its width and height (PROTOCOL §1.2)."""

FRONT, BACK, LEFT, RIGHT, TOP, BOTTOM = "front", "back", "left", "right", "top", "bottom"
FRONT_TOP, BACK_BOTTOM = "front_top", "back_bottom"
DASHBOARD = "dashboard"
ORTHOGRAPHIC_VIEWS = (FRONT, BACK, LEFT, RIGHT, TOP, BOTTOM)
AXONOMETRIC_VIEWS = (FRONT_TOP, BACK_BOTTOM)
STANDARD_VIEWS = ORTHOGRAPHIC_VIEWS + AXONOMETRIC_VIEWS
VIEWS = STANDARD_VIEWS + (DASHBOARD,)
"""Every view name, in PROTOCOL §3.1's order (the standard views, then the dashboard): the
order in which the synthetic benchmark lists a device's views and a component's boxes in its
SSM (the planner's preference is `VIEW_ORDER`)."""
VIEW_ORDER = ORTHOGRAPHIC_VIEWS + (DASHBOARD,) + AXONOMETRIC_VIEWS
"""Planner tie-break order of views (PROTOCOL §4.3); also the order of the views a device
offers, of the environments' view codes and of the kernel's."""
VIEW_RANK = {v: i for i, v in enumerate(VIEW_ORDER)}

PRESS, ROTATE, PUSH, PULL, GRASP = "press", "rotate", "push", "pull", "grasp"
INTERACTIONS = (PRESS, ROTATE, PUSH, PULL, GRASP)
ATOMIC_ACTIONS = frozenset(INTERACTIONS)
SWITCH_VIEW = "switch_view"
TIMED_WAIT = "timed_wait"
ACTION_NAMES = INTERACTIONS + (SWITCH_VIEW, TIMED_WAIT)
"""Lowercase action names of the grammar (PROTOCOL §2)."""
DISPLAY_NAMES = {name: name[0].upper() + name[1:] for name in ACTION_NAMES}
"""How the grammar writes each action (`Press`, ..., `Switch_view`, `Timed_wait`)."""

# Parameter codes: the action space the prompt teaches (the paper's), which the environments'
# parameter lists and the synthetic devices use (PROTOCOL §2). A code is its position here;
# matching compares whatever an SSM lists (PROTOCOL §1.2), so they are a convention, not a rule.
PRESS_KINDS = ("a short press", "a long press (held more than a second)", "a double press")
"""`Press(params=[kind])`."""
ROTATE_DIRECTIONS = ("clockwise", "counter-clockwise")
"""`Rotate(params=[direction, notches])`'s first parameter; the second counts notches."""
ROTATE_NOTCHES = (1, 2, 3, 4)
"""The notch counts `vge/DeviceRL-v0` offers (a transition's `*` accepts any)."""
PUSH_DIRECTIONS = (
    "up",
    "down",
    "left",
    "right",
    "in or forward (closing a door, inserting a plug)",
)
"""`Push(params=[direction])`."""
PULL_DIRECTIONS = PUSH_DIRECTIONS[:4] + ("out or backward (opening a door, pulling a drawer out)",)
"""`Pull(params=[direction])`: as Push's, the last one outwards."""
GRASP_STATES = ("take hold or pick up", "let go or put down")
"""`Grasp(params=[state])`."""
PARAMETER_CODES: dict[str, tuple[str, ...]] = {
    PRESS: PRESS_KINDS,
    ROTATE: ROTATE_DIRECTIONS,
    PUSH: PUSH_DIRECTIONS,
    PULL: PULL_DIRECTIONS,
    GRASP: GRASP_STATES,
}
"""Each interaction's first parameter: code `i` means entry `i`."""
PARAMETER_NAMES: dict[str, tuple[str, ...]] = {
    PRESS: ("kind",),
    ROTATE: ("direction", "steps"),
    PUSH: ("direction",),
    PULL: ("direction",),
    GRASP: ("state",),
}
"""What an interaction's parameters are called, in order (`Rotate(params=[direction, steps])`)."""


def codes_text(action: str) -> str:
    """`0 a short press, 1 ..., 2 a double press`: the codes of an interaction's first parameter."""
    return ", ".join(f"{code} {meaning}" for code, meaning in enumerate(PARAMETER_CODES[action]))


IMMEDIATE = "immediate"
PSEUDO_COMPONENTS = frozenset({IMMEDIATE, TIMED_WAIT})
"""Keys of a state's `on` that are not components."""

# Feedback kinds (PROTOCOL §3): the contract; the texts live in `_feedback.py`.
FB_INVALID = "invalid_action"
FB_SWITCHED = "view_switched"
FB_TRANSITION = "transition"
FB_WAIT_NO_EFFECT = "wait_no_effect"
FB_UNLOCKED = "dashboard_unlocked"
FB_OPERATIONAL = "operational_error"
FB_NULL = "null_effect"
FEEDBACK_KINDS = (
    FB_INVALID,
    FB_SWITCHED,
    FB_TRANSITION,
    FB_WAIT_NO_EFFECT,
    FB_UNLOCKED,
    FB_OPERATIONAL,
    FB_NULL,
)

# Error taxonomy (PROTOCOL §5) and its groups.
ERROR_GROUPS = {
    "invalid_coord": "grounding",
    "component_selection": "grounding",
    "params_error": "execution",
    "action_error": "execution",
    "invalid_waiting": "execution",
    "switch_view_nn": "navigation",
    "switch_view_pn": "navigation",
}
ERROR_TYPES = tuple(ERROR_GROUPS)
SWITCH_CLASSES = ("NP", "PN", "NN", "PP")

SUCCESS = "success"
BUDGET_GLOBAL = "budget_global"
BUDGET_LOCAL = "budget_local"
LOG_ENDED = "log_ended"
CONTEXT_EXCEEDED = "context_exceeded"
TERMINATIONS = (SUCCESS, BUDGET_GLOBAL, BUDGET_LOCAL, LOG_ENDED, CONTEXT_EXCEEDED)
"""How an episode ends (PROTOCOL §3.5), in the order of the kernel's codes: a new one goes
last so that the codes of the others never change."""

PARSE_DETAILS = ("no_action", "multiple_actions", "unknown_action", "malformed")
"""Why a response did not parse (PROTOCOL §2)."""
INVALID_DETAILS = PARSE_DETAILS + (
    "axonometric_view",
    "missing_coord",
    "out_of_range",
    "invalid_view",
    "locked_dashboard",
)
"""Why a step got `invalid_action` feedback (PROTOCOL §3)."""
ERROR_DETAILS = INVALID_DETAILS + ("wrong_action", "no_effect")
"""Every `error_detail` value (PROTOCOL §5)."""

DEFAULT_LAMBDA = 5.0


_NORMALIZED: dict[str, str] = {}


def normalize_param(value: object) -> str:
    """Canonical string of a parameter value, memoised for strings (a small vocabulary)."""
    if type(value) is str:
        got = _NORMALIZED.get(value)
        if got is None:
            got = _normalize_param(value)
            if len(_NORMALIZED) < 65536:
                _NORMALIZED[value] = got
        return got
    return _normalize_param(value)


def _normalize_param(value: object) -> str:
    """Canonical string of a parameter value: trimmed, unquoted, lowercase, numbers canonical.

    `"1.0"`, `1`, `"01"`, `" '1' "` all become `"1"`; `"*"` stays `"*"`.
    """
    if isinstance(value, bool):
        return "1" if value else "0"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return _number_text(value)
    text = str(value).strip()
    while len(text) >= 2 and text[0] == text[-1] and text[0] in "'\"`":
        text = text[1:-1].strip()
    text = text.lower()
    if text and (text[0].isdigit() or text[0] in "+-."):
        try:
            number = float(text)
        except ValueError:
            return text
        return _number_text(number)
    return text


def _number_text(number: float) -> str:
    if math.isfinite(number) and number == int(number):
        return str(int(number))
    return repr(number)


def normalize_params(values: object) -> tuple[str, ...]:
    """Normalise a params list (or a single scalar) to a tuple of canonical strings."""
    if values is None:
        return ()
    if isinstance(values, (list, tuple)):
        return tuple(normalize_param(v) for v in values)
    return (normalize_param(values),)
