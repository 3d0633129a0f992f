"""Feedback texts and severities, in one place (PROTOCOL §3.6: the kind is the contract, the
text may improve)."""

from __future__ import annotations

from . import _vocab as v

_NAMES = [v.DISPLAY_NAMES[name] for name in v.ACTION_NAMES]
_INVALID_REASONS = {
    "no_action": "no action was found; answer with one 'Action:' line such as "
    "Press(coord=[x, y], params=[0]).",
    "multiple_actions": "exactly one action per response is allowed.",
    "unknown_action": f"unknown action; use {', '.join(_NAMES[:-1])} or {_NAMES[-1]}.",
    "malformed": "the action could not be parsed; use ActionName(coord=[x, y], params=[...]).",
    "axonometric_view": "physical interactions are not allowed in an axonometric view; "
    "use Switch_view first.",
    "missing_coord": "this action needs a target: coord=[x, y].",
    "out_of_range": f"coordinates must lie within the image, 0..{v.SCALE} on both axes.",
    "invalid_view": "that view is not available for this device.",
    "locked_dashboard": "the dashboard is locked; point at the dashboard region with "
    "Switch_view(coord=[x, y], params=[dashboard]) to unlock it.",
}

INFO, WARNING, ERROR = "info", "warning", "error"
SEVERITIES = (INFO, WARNING, ERROR)
"""How serious a feedback is, mildest first (PROTOCOL §3.6)."""
FEEDBACK_SEVERITY: dict[str, str] = {
    v.FB_INVALID: ERROR,
    v.FB_SWITCHED: INFO,
    v.FB_TRANSITION: INFO,
    v.FB_WAIT_NO_EFFECT: WARNING,
    v.FB_UNLOCKED: INFO,
    v.FB_OPERATIONAL: ERROR,
    v.FB_NULL: WARNING,
}
"""The severity of each feedback kind (PROTOCOL §3.6), in `FEEDBACK_KINDS` order: the MCAP
writer's log level (§7.8) and the Play page's colour."""

OPERATIONAL_TEXT = "It seems that this component can be operated, but not in this way."
NULL_TEXT = "Nothing happened."
WAIT_NO_EFFECT_TEXT = "You waited, but nothing changed."
UNLOCKED_TEXT = (
    "The dashboard is now unlocked; the action was not carried out. "
    "Switch to the dashboard view to operate it."
)


def invalid_text(detail: str) -> str:
    return "System Notification: " + _INVALID_REASONS.get(detail, "invalid action.")


def switched_text(view: str, unlocked_now: bool) -> str:
    if unlocked_now:
        return "The dashboard is unlocked; switched to the dashboard view."
    return f"Switched to the {view} view."


def transition_text(description: str, state_description: str) -> str:
    first = description.strip().rstrip(".")
    second = state_description.strip().rstrip(".")
    if first and second:
        return f"{first}. Now: {second}."
    return (first or second or "The device changed state") + "."
