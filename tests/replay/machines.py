"""Small hand-written state machines for engine tests (built in code, compiled for real)."""

from __future__ import annotations

import msgspec

from replay import Machine, StateMachine, compile_machine


def box(view: str, x: float, y: float, w: float, h: float) -> dict:
    """A bbox given directly on the 0..1000 scale (W = H = 1000)."""
    return {"coordinate": [x, y, w, h, 1000, 1000], "view": view}


def tr(
    next_state: str, action: str | None = "press", params=("0",), boxes=(), text: str = ""
) -> dict:
    out: dict = {"next_state": next_state, "transition_description": text or f"to {next_state}"}
    if action is not None:
        out.update(atomic_action=action, parameter=list(params), bbox=list(boxes))
    return out


def machine(states: dict[str, dict[str, list[dict]]], initial: str, **extra) -> Machine:
    doc = {
        "name": extra.pop("name", "TestDevice"),
        "initial_state": initial,
        "states": {name: {"description": f"{name} state", "on": on} for name, on in states.items()},
        **extra,
    }
    return compile_machine(msgspec.convert(doc, StateMachine), device_id="dev")
