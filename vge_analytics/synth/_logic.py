"""The logical half of SSM instantiation: which components a device has and how exactly they
are operated (paper, section "Annotation and State Machine Design").

From the category UCSM: drop the optional components this device lacks, vary the operation
of some components in ways a real instance could differ (a knob turning the other way, a
button that needs a long press, a slider lying horizontally), then remove the states that
became unreachable. The result is the SSM without geometry (no bboxes yet).
"""

from __future__ import annotations

import random
from collections import deque
from dataclasses import dataclass

from ._catalog import Catalog, load_catalog, load_ucsm

SPECIAL = ("immediate", "timed_wait")

OPTIONAL_KEEP = 0.42
"""Chance that a device has a given optional component (tuned to the paper's ~3.8 unique
components and ~16 transitions per device; see docs/SYNTHETIC.md)."""

# Per-component variations: (probability, action, bijection on one parameter position).
_PRESS_SWAP = {"0": "1", "1": "0"}
_DIR_SWAP = {"0": "1", "1": "0"}
_PUSH_FLIP_V = {"0": "1", "1": "0"}
_PUSH_FLIP_H = {"2": "3", "3": "2"}
_PUSH_TURN = {"0": "2", "1": "3", "2": "0", "3": "1"}


@dataclass(frozen=True, slots=True)
class DeviceLogic:
    """A device's state machine without geometry, plus what geometry needs to know."""

    device_id: str
    category: str
    components: tuple[str, ...]
    """Components the device has (catalog order), each used by some reachable transition."""
    machine: dict
    """Paper-format SSM without bboxes: name, initial_state, states."""


def instantiate_logic(
    category: str, device_id: str, rng: random.Random, *, optional_keep: float = OPTIONAL_KEEP
) -> DeviceLogic:
    """Prune and vary the category's UCSM for one device."""
    ucsm = load_ucsm(category)
    catalog = load_catalog(category)
    names = list(catalog.components)
    kept = {n for n in names if catalog.components[n].required}
    for n in names:
        if not catalog.components[n].required and rng.random() < optional_keep:
            kept.add(n)
    variations = {n: _choose_variation(ucsm, n, rng) for n in names if n in kept}

    states: dict[str, dict] = {}
    for sname, sdef in ucsm["states"].items():
        on: dict[str, list[dict]] = {}
        for comp, trans in sdef["on"].items():
            if comp not in SPECIAL and comp not in kept:
                continue
            on[comp] = [_vary(t, variations.get(comp)) for t in trans]
        states[sname] = {"description": sdef["description"], "on": on}
        if sdef.get("is_error"):
            states[sname]["is_error"] = True

    reachable = _reachable(states, ucsm["initial_state"])
    states = {s: d for s, d in states.items() if s in reachable}
    used = {c for d in states.values() for c in d["on"] if c not in SPECIAL}
    machine = {"name": ucsm["name"], "initial_state": ucsm["initial_state"], "states": states}
    return DeviceLogic(device_id, category, tuple(n for n in names if n in used), machine)


def _reachable(states: dict[str, dict], start: str) -> set[str]:
    seen = {start}
    todo = deque([start])
    while todo:
        s = todo.popleft()
        for trans in states[s]["on"].values():
            for t in trans:
                n = t["next_state"]
                if n not in seen:
                    seen.add(n)
                    todo.append(n)
    return seen


def _component_actions(ucsm: dict, component: str) -> list[tuple[str, list[str]]]:
    out = []
    for sdef in ucsm["states"].values():
        for t in sdef["on"].get(component, ()):
            out.append((t["atomic_action"], list(t.get("parameter") or [])))
    return out


def _choose_variation(ucsm: dict, component: str, rng: random.Random) -> dict | None:
    """A consistent re-mapping of this component's parameters, or None (as in the UCSM).

    Every mapping is a bijection per parameter position, so transitions that were
    distinguishable stay distinguishable. Draws are made in a fixed order whatever applies,
    so one component's data does not shift another's choices."""
    uses = _component_actions(ucsm, component)
    actions = {a for a, _ in uses}
    draws = [rng.random() for _ in range(4)]
    variation: dict[str, dict[int, dict[str, str]]] = {}
    if "rotate" in actions:
        rot: dict[int, dict[str, str]] = {}
        if draws[0] < 0.25:
            rot[0] = _DIR_SWAP
        if rot:
            variation["rotate"] = rot
    presses = {tuple(p) for a, p in uses if a == "press"}
    if actions == {"press"} and presses == {("0",)} and draws[2] < 0.2:
        variation["press"] = {0: _PRESS_SWAP}  # this instance needs a long press
    if actions & {"push", "pull"}:
        dirs = {p[0] for a, p in uses if a in ("push", "pull") and p}
        if dirs and dirs <= {"0", "1", "2", "3"}:
            if draws[3] < 0.25:
                mapping = _PUSH_TURN
            elif draws[3] < 0.4:
                mapping = _PUSH_FLIP_V if dirs & {"0", "1"} else _PUSH_FLIP_H
            else:
                mapping = None
            if mapping is not None:
                variation["push"] = {0: mapping}
                variation["pull"] = {0: mapping}
    return variation or None


def _vary(transition: dict, variation: dict | None) -> dict:
    out = {
        "next_state": transition["next_state"],
        "transition_description": transition["transition_description"],
    }
    action = transition.get("atomic_action")
    if action is None:
        return out
    params = [str(p) for p in (transition.get("parameter") or [])]
    rule = (variation or {}).get(action)
    if rule:
        for pos, mapping in rule.items():
            if pos >= len(params):
                continue
            params[pos] = mapping.get(params[pos], params[pos])
    out["atomic_action"] = action
    out["parameter"] = params
    return out


def catalog_of(logic: DeviceLogic) -> Catalog:
    return load_catalog(logic.category)
