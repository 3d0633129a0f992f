"""What a simulated VLM writes: the `Thinking:` text and the `Action:` line (PROTOCOL §2), with
the harmless decorations real models add and the format slips they make.

Texts are built from the catalog (what a component looks like, its printed label, where it
is in the image), never from the SSM's internal component names, as a model only sees the
picture.
"""

from __future__ import annotations

import random

import replay
from replay.semantics import (
    GRASP,
    PRESS,
    PULL,
    PUSH,
    ROTATE,
    ROTATE_DIRECTIONS,
    SWITCH_VIEW,
    TIMED_WAIT,
)

from ._catalog import ComponentSpec

KIND_NOUNS = {
    "button": "button",
    "touch_pad": "touch pad",
    "key": "key",
    "trigger": "trigger",
    "shutter_button": "shutter button",
    "knob": "knob",
    "dial": "dial",
    "wheel": "wheel",
    "ring": "ring",
    "crank": "crank",
    "lens": "lens",
    "slider": "slider",
    "switch": "switch",
    "rocker": "rocker switch",
    "lever": "lever",
    "door": "door",
    "lid": "lid",
    "cover": "cover",
    "drawer": "drawer",
    "basket": "basket",
    "tank": "removable container",
    "tray": "tray",
    "cap": "cap",
    "head": "head",
    "nozzle": "nozzle",
    "attachment": "attachment",
    "port": "port",
    "plug": "plug",
    "cable": "cable",
    "handle": "handle",
    "grip": "grip",
    "handset": "handset",
    "body": "body",
    "platform": "platform",
    "blade": "blade",
}
_DIRECTIONS = {"0": "up", "1": "down", "2": "to the left", "3": "to the right", "4": "in"}
_PULL_DIRECTIONS = {"0": "up", "1": "down", "2": "to the left", "3": "to the right", "4": "out"}


def describe(spec: ComponentSpec | None, rect: tuple[float, ...] | None, view: str) -> str:
    """'the round knob labeled "POWER" in the lower right of the front view'."""
    if spec is None:
        noun = "control"
        label = ""
    else:
        noun = KIND_NOUNS.get(spec.kind, spec.kind.replace("_", " "))
        label = _label_text(spec.label)
    where = f" {position_words(rect)} of the {view.replace('_', ' ')} view" if rect else ""
    return f"the {noun}{label}{where}"


def _label_text(label: str) -> str:
    if not label:
        return ""
    if label.startswith("icon:"):
        name = label[5:].replace("_", " ")
        article = "an" if name[:1] in "aeiou" else "a"
        return f" with {article} {name} icon"
    return f' labeled "{label}"'


def position_words(rect: tuple[float, ...]) -> str:
    cx = (rect[0] + rect[2]) / 2.0
    cy = (rect[1] + rect[3]) / 2.0
    col = "left" if cx < 340 else "right" if cx > 660 else "center"
    row = "upper" if cy < 340 else "lower" if cy > 660 else "middle"
    if row == "middle" and col == "center":
        return "in the center"
    if row == "middle":
        return f"on the {col} side"
    if col == "center":
        return f"in the {row} middle"
    return f"in the {row} {col}"


def verb_phrase(action: replay.Action) -> str:
    """'turn it clockwise by 2 steps', 'press and hold it', 'pull it out'."""
    p = action.params
    if action.type == PRESS:
        return {"1": "press and hold it", "2": "double-press it"}.get(
            p[0] if p else "0", "press it"
        )
    if action.type == ROTATE:
        direction = ROTATE_DIRECTIONS[0 if (p[:1] or ("0",))[0] == "0" else 1]
        extent = p[1] if len(p) > 1 else "*"
        if extent in ("*", ""):
            return f"turn it {direction}"
        unit = "step" if extent == "1" else "steps"
        return f"turn it {direction} by {extent} {unit}"
    if action.type == PUSH:
        return f"push it {_DIRECTIONS.get(p[0] if p else '4', 'in')}"
    if action.type == PULL:
        return f"pull it {_PULL_DIRECTIONS.get(p[0] if p else '4', 'out')}"
    if action.type == GRASP:
        return "let go of it" if p[:1] == ("1",) else "pick it up"
    return "operate it"


def action_text(action: replay.Action, rng: random.Random, decorated: float) -> str:
    """The `Action:` line, sometimes decorated in ways the grammar accepts."""
    call = action.to_text()
    x = rng.random()
    if x >= decorated:
        return f"Action: {call}"
    style = rng.randrange(5)
    if style == 0:
        return f"**Action:** {call}"
    if style == 1:
        return f"Action: `{call}`"
    if style == 2:
        return f"Action: {call}."
    if style == 3 and action.params:
        quoted = ", ".join(f"'{p}'" for p in action.params)
        return "Action: " + call.replace(
            "params=[" + ", ".join(action.params) + "]", f"params=[{quoted}]"
        )
    return f"Action:\n```\n{call}\n```"


SLIP_KINDS = ("unknown_action", "multiple_actions", "no_action", "malformed")


def slip_text(kind: str, thinking: str, action: replay.Action, alternative: replay.Action) -> str:
    """A response that fails to parse with detail `kind` (PROTOCOL §2)."""
    coord = action.coord or (500.0, 500.0)
    x, y = round(coord[0]), round(coord[1])
    if kind == "unknown_action":
        name = "Click" if action.type in (PRESS, SWITCH_VIEW, TIMED_WAIT) else "Tap"
        return f"Thinking: {thinking}\nAction: {name}(coord=[{x}, {y}])"
    if kind == "multiple_actions":
        return f"Thinking: {thinking}\nAction: {alternative.to_text()}\nAction: {action.to_text()}"
    if kind == "no_action":
        return f"Thinking: {thinking} I will {verb_phrase(action)} at [{x}, {y}]."
    params = ", ".join(action.params)
    name = action.to_text().split("(", 1)[0]
    return f"Thinking: {thinking}\nAction: {name}(coord=[{x} {y}], params=[{params}])"


def intent_text(instruction: str) -> str:
    text = instruction.strip().rstrip(".!")
    if not text:
        return "The user wants me to operate the device."
    return f'The user asks: "{text}".'
