"""The ReAct prompt of the `openai:MODEL` agent: the rules of the device world (the system
message) and one user message per step.

Built like the paper's appendix (output format, coordinate system, action space, constraints,
examples), in our own words, and kept in step with the grammar the replay parses (PROTOCOL
§2) and the simulator's rules (PROTOCOL §3).
"""

from __future__ import annotations

import base64
import io
from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple

import numpy as np
from PIL import Image

from replay.semantics import (
    AXONOMETRIC_VIEWS,
    BOTTOM,
    DASHBOARD,
    DISPLAY_NAMES,
    GRASP,
    ORTHOGRAPHIC_VIEWS,
    PARAMETER_NAMES,
    PRESS,
    PULL,
    PUSH,
    ROTATE,
    SCALE,
    SWITCH_VIEW,
    TIMED_WAIT,
    codes_text,
)


def _call(action: str) -> str:
    """`Press(coord, params=[kind])`: an interaction as the prompt shows it."""
    return f"{DISPLAY_NAMES[action]}(coord, params=[{', '.join(PARAMETER_NAMES[action])}])"


def _first(action: str) -> str:
    """`kind: 0 a short press, ...`: the codes of the interaction's first parameter."""
    return f"{PARAMETER_NAMES[action][0]}: {codes_text(action)}"


_N = DISPLAY_NAMES
_ORTHOGRAPHIC = ", ".join(ORTHOGRAPHIC_VIEWS[:-1]) + f" and {ORTHOGRAPHIC_VIEWS[-1]}"
_AXONOMETRIC = " and ".join(AXONOMETRIC_VIEWS)

SYSTEM_PROMPT = f"""\
You operate household devices by looking at pictures of them. Each turn you get the user's \
request, the view of the device you are looking at, and what happened after your last action. \
You answer with one action.

## 1. How to answer
Write exactly two parts:
Thinking: what you see in the picture, which part of the device can do what the user asks \
(a button, a knob, a door, a lid, or a process that only needs time), and why you choose \
your action. If the part you need is not in this view, or the device is still busy, say so \
and choose an action that does not touch the device.
Action: one call, written as Name(coord=[x, y], params=[...]). Leave out coord for an \
action that needs no point.

## 2. Coordinates
Points are given on the picture you see, whatever its pixel size: x runs from 0 (left edge) \
to {SCALE} (right edge), y from 0 (top edge) to {SCALE} (bottom edge), both as whole numbers. \
[0, 0] is the top-left corner, [{SCALE}, {SCALE}] the bottom-right one.

## 3. Actions
- {_call(PRESS)}: buttons, touch areas, switches, triggers. {_first(PRESS)}.
- {_call(ROTATE)}: knobs, dials, keys, winders. {_first(ROTATE)}; \
{PARAMETER_NAMES[ROTATE][1]}: how many notches. Either may be * when it does not matter.
- {_call(PUSH)}: sliding, closing, inserting. {_first(PUSH)}.
- {_call(PULL)}: opening, lifting off, unplugging. {_first(PULL)}.
- {_call(GRASP)}: handles and handheld devices. {_first(GRASP)}.
- {_N[SWITCH_VIEW]}(params=[view]): look at the device from another side. view is one of the \
views listed for the device. Use it when what you need is not visible here.
- {_N[TIMED_WAIT]}(): let time pass while the device finishes something it is doing.

## 4. Views
The standard views are {_ORTHOGRAPHIC}, looked at straight on, and \
two angled overviews, {_AXONOMETRIC}. In an angled overview nothing can be \
operated: only {_N[SWITCH_VIEW]} works there. Large devices may also offer a {DASHBOARD} view, a \
close-up of the control panel. While it is listed as "{DASHBOARD} (locked)" you cannot switch \
to it by name alone. Unlock it in one of two ways:
- {_N[SWITCH_VIEW]}(coord=[x, y], params=[{DASHBOARD}]) with the point on the control panel in \
the current view: the dashboard unlocks and you see it at once.
- Any other action with its point on the control panel: the dashboard unlocks, but that \
action does nothing and the view stays as it is.
Once unlocked, the dashboard is a view like the others; operate the panel's controls there.

## 5. Rules
Give exactly one Action per answer: a single call, never two.

## 6. Examples
Thinking: The user wants the fan faster. On the front I see a round knob marked with speed \
levels, set to 1; level 3 is two notches clockwise. I will turn it two notches clockwise.
Action: {_N[ROTATE]}(coord=[512, 640], params=[0, 2])

Thinking: The user wants the battery compartment opened. Nothing on this side looks like a \
cover, and such compartments are often underneath, so I will look at the bottom.
Action: {_N[SWITCH_VIEW]}(params=[{BOTTOM}])

Thinking: The rice is still cooking and the lid is locked while it does. I have to wait \
until it finishes.
Action: {_N[TIMED_WAIT]}()

Thinking: The labels of the buttons on the panel are too small to read from here. I will \
move closer to the panel at the top right of the picture.
Action: {_N[SWITCH_VIEW]}(coord=[780, 210], params=[{DASHBOARD}])
"""
"""The system message: the grammar (PROTOCOL §2), the scale, the actions with their parameter
codes and the views (PROTOCOL §3), all named from `replay.semantics`."""


def png_data_url(image: np.ndarray) -> str:
    """The image as a `data:image/png;base64,...` URL."""
    buf = io.BytesIO()
    Image.fromarray(np.asarray(image, dtype=np.uint8)).save(buf, format="PNG", compress_level=6)
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


def views_text(obs: Mapping[str, Any]) -> str:
    """The views of the device, the locked dashboard marked as such."""
    names = []
    for view in obs["views"]:
        if view == DASHBOARD and not obs["dashboard_unlocked"]:
            names.append(f"{DASHBOARD} (locked)")
        else:
            names.append(view)
    return ", ".join(names)


def observation_text(obs: Mapping[str, Any], last_action: str | None) -> str:
    """What the user message says at a step (the picture is attached beside it)."""
    n_goals = int(obs["n_goals"])
    lines = [f"Request: {obs['instruction']}"]
    if n_goals > 1:
        lines.append(f"(part {int(obs['goal_index']) + 1} of {n_goals} of the task)")
    lines += [
        f"Current view: {obs['view']}",
        f"Views of this device: {views_text(obs)}",
    ]
    if last_action is None:
        lines.append("This is your first action.")
    else:
        lines.append(f"Your last action: {last_action or '(it could not be read)'}")
        lines.append(f"What happened: {obs['feedback']}")
    return "\n".join(lines)


class Turn(NamedTuple):
    """One past step of the conversation."""

    said: str
    """The step's user message text."""
    image_url: str
    """The picture it showed."""
    answered: str
    """The model's answer."""


def build_messages(
    history: Sequence[Turn], current: str, image_url: str, *, images: int | None = None
) -> list[dict[str, Any]]:
    """System rules, the past turns kept (what was said, with its picture for the latest
    `images` of them, None: all; and what was answered), then the current step with its
    picture."""
    messages: list[dict[str, Any]] = [{"role": "system", "content": SYSTEM_PROMPT}]
    pictured = len(history) if images is None else min(images, len(history))
    for i, turn in enumerate(history):
        if i >= len(history) - pictured:
            messages.append(_user(turn.said, turn.image_url))
        else:
            messages.append({"role": "user", "content": turn.said})
        messages.append({"role": "assistant", "content": turn.answered})
    messages.append(_user(current, image_url))
    return messages


def _user(text: str, image_url: str) -> dict[str, Any]:
    return {
        "role": "user",
        "content": [
            {"type": "text", "text": text},
            {"type": "image_url", "image_url": {"url": image_url}},
        ],
    }


__all__ = [
    "SYSTEM_PROMPT",
    "Turn",
    "build_messages",
    "observation_text",
    "png_data_url",
    "views_text",
]
