"""The fixed vocabulary: views, action names, feedback kinds, error types, and the
normalisation of parameter values. One place, so every module agrees."""

from __future__ import annotations

import math

SCALE = 1000
"""The agent's coordinate scale: a point is `[x, y]` with 0..SCALE on both axes of a view,
relative to its width and height (PROTOCOL §1.2)."""

ORTHOGRAPHIC_VIEWS = ("front", "back", "left", "right", "top", "bottom")
AXONOMETRIC_VIEWS = ("front_top", "back_bottom")
DASHBOARD = "dashboard"
STANDARD_VIEWS = ORTHOGRAPHIC_VIEWS + AXONOMETRIC_VIEWS
VIEW_ORDER = ("front", "back", "left", "right", "top", "bottom", DASHBOARD) + AXONOMETRIC_VIEWS
"""Planner tie-break order of views (PROTOCOL §4)."""
VIEW_RANK = {v: i for i, v in enumerate(VIEW_ORDER)}

INTERACTIONS = ("press", "rotate", "push", "pull", "grasp")
ATOMIC_ACTIONS = frozenset(INTERACTIONS)
SWITCH_VIEW = "switch_view"
TIMED_WAIT = "timed_wait"
ACTION_NAMES = INTERACTIONS + (SWITCH_VIEW, TIMED_WAIT)
"""Lowercase action names of the grammar (PROTOCOL §2)."""
DISPLAY_NAMES = {
    "press": "Press",
    "rotate": "Rotate",
    "push": "Push",
    "pull": "Pull",
    "grasp": "Grasp",
    SWITCH_VIEW: "Switch_view",
    TIMED_WAIT: "Timed_wait",
}

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

TERMINATIONS = ("success", "budget_global", "budget_local", "log_ended", "context_exceeded")
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
