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

from replay.semantics import IMMEDIATE, PRESS, PULL, PUSH, ROTATE, TIMED_WAIT

from ._catalog import load_catalog, load_ucsm

NON_COMPONENTS = (IMMEDIATE, TIMED_WAIT)

OPTIONAL_KEEP = 0.3
"""Default chance that a device has a given optional component."""
FUNCTION_DROP = 0.0
"""Default chance that a device lacks a given optional function (state)."""
CATEGORY_PRUNING: dict[str, tuple[float, float]] = {
    "AirFryer": (0.0, 0.0),
    "AirPurifier": (0.2, 0.15),
    "CarKey": (0.3, 0.9),
    "CoffeeMachine": (0.0, 0.3),
    "DigitalAlarmClock": (0.0, 0.9),
    "DigitalCamera": (0.1, 0.45),
    "ElectricFan": (0.4, 0.0),
    "ElectricKettle": (0.85, 0.9),
    "ElectricToothbrush": (0.3, 0.3),
    "FilmCamera": (0.0, 0.0),
    "Flashlight": (0.3, 0.75),
    "HairDryer": (0.7, 0.0),
    "Heater": (0.3, 0.9),
    "Humidifier": (0.2, 0.9),
    "Lamp": (0.0, 0.0),
    "Landline": (0.1, 0.9),
    "Lighter": (0.3, 0.9),
    "MechanicalAlarmClock": (0.0, 0.9),
    "Microwave": (0.0, 0.45),
    "PowerBank": (0.2, 0.9),
    "Razor": (0.3, 0.75),
    "RiceCooker": (0.2, 0.0),
    "ThermometerGun": (0.0, 0.75),
    "Vacuum": (0.2, 0.9),
    "WashingMachine": (0.0, 0.3),
    "WeighingScale": (0.4, 0.75),
}
"""Per category (optional component keep rate, function drop rate), calibrated so the mean
number of operable transitions per device follows the paper's per-category action counts
(Table "atomic actions") and the totals its statistics table (docs/SYNTHETIC.md)."""

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


def pruning_rates(category: str) -> tuple[float, float]:
    """(chance to keep an optional component, chance to drop an optional function)."""
    return CATEGORY_PRUNING.get(category, (OPTIONAL_KEEP, FUNCTION_DROP))


def instantiate_logic(
    category: str,
    device_id: str,
    rng: random.Random,
    *,
    optional_keep: float | None = None,
    function_drop: float | None = None,
    force: frozenset[str] = frozenset(),
) -> DeviceLogic:
    """Prune and vary the category's UCSM for one device; `force` names optional components
    the device must have (the controls of its dashboard)."""
    keep_p, drop_p = pruning_rates(category)
    keep_p = keep_p if optional_keep is None else optional_keep
    drop_p = drop_p if function_drop is None else function_drop
    ucsm = load_ucsm(category)
    catalog = load_catalog(category)
    names = list(catalog.components)
    kept = {n for n in names if catalog.components[n].required} | set(force)
    for n in names:
        draw = rng.random()
        if not catalog.components[n].required and draw < keep_p:
            kept.add(n)
    variations = {n: _choose_variation(ucsm, n, rng) for n in names if n in kept}

    states: dict[str, dict] = {}
    for sname, sdef in ucsm["states"].items():
        on: dict[str, list[dict]] = {}
        for comp, trans in sdef["on"].items():
            if comp not in NON_COMPONENTS and comp not in kept:
                continue
            on[comp] = [_vary(t, variations.get(comp)) for t in trans]
        states[sname] = {"description": sdef["description"], "on": on}
        if sdef.get("is_error"):
            states[sname]["is_error"] = True

    reachable = _reachable(states, ucsm["initial_state"])
    states = {s: d for s, d in states.items() if s in reachable}
    states = _drop_functions(states, ucsm["initial_state"], set(catalog.goal_phrases), drop_p, rng)
    used = {c for d in states.values() for c in d["on"] if c not in NON_COMPONENTS}
    machine = {"name": ucsm["name"], "initial_state": ucsm["initial_state"], "states": states}
    return DeviceLogic(device_id, category, tuple(n for n in names if n in used), machine)


def _is_error(name: str, sdef: dict) -> bool:
    return name == "Error" or bool(sdef.get("is_error"))


def _without(states: dict[str, dict], drop: set[str], initial: str) -> dict[str, dict] | None:
    """`states` minus `drop`, the transitions into them, the settling states that led only
    into them, and what became unreachable; None if that would remove the initial state."""
    drop = set(drop)
    while True:
        more = set()
        for sname, sdef in states.items():
            if sname in drop:
                continue
            imm = sdef["on"].get(IMMEDIATE)
            if imm and imm[0]["next_state"] in drop:
                more.add(sname)
        if not more:
            break
        drop |= more
    if initial in drop:
        return None
    out: dict[str, dict] = {}
    for sname, sdef in states.items():
        if sname in drop:
            continue
        on = {}
        for comp, trans in sdef["on"].items():
            kept = [t for t in trans if t["next_state"] not in drop]
            if kept:
                on[comp] = kept
        out[sname] = {**sdef, "on": on}
    reachable = _reachable(out, initial)
    return {s: d for s, d in out.items() if s in reachable}


def _returns_home(states: dict[str, dict], initial: str) -> bool:
    """Every state can get back to the initial state."""
    reverse: dict[str, set[str]] = {s: set() for s in states}
    for sname, sdef in states.items():
        for trans in sdef["on"].values():
            for t in trans:
                reverse[t["next_state"]].add(sname)
    seen = {initial}
    todo = deque([initial])
    while todo:
        s = todo.popleft()
        for p in reverse[s]:
            if p not in seen:
                seen.add(p)
                todo.append(p)
    return seen == set(states)


def _drop_functions(
    states: dict[str, dict], initial: str, phrased: set[str], drop_p: float, rng: random.Random
) -> dict[str, dict]:
    """Remove some functions (states) this device lacks, e.g. a microwave without a medium
    power level, as long as the machine stays usable: every state can return to the initial
    one, every component keeps a use, and at least two goal states remain. A settling state
    that passes the device on to another state is never dropped on its own (`_passes_on`)."""

    def used(st: dict[str, dict]) -> set[str]:
        return {c for d in st.values() for c in d["on"] if c not in NON_COMPONENTS}

    for sname in list(states):
        draw = rng.random()
        if sname not in states or sname == initial or _is_error(sname, states[sname]):
            continue
        if _passes_on(states, sname):
            continue
        if draw >= drop_p:
            continue
        candidate = _without(states, {sname}, initial)
        if candidate is None or not _returns_home(candidate, initial):
            continue
        if used(candidate) != used(states):
            continue
        goals = {
            s for s, d in candidate.items() if s in phrased and s != initial and not _is_error(s, d)
        }
        if len(goals) < 2:
            continue
        states = candidate
    return states


def _passes_on(states: dict[str, dict], name: str) -> bool:
    """True for a settling state that passes the device on to another state (the drum
    filling before a wash, a finished brew before the machine is ready again): it is part
    of the transitions that enter it, not a function of its own. A settling state that
    returns the device to where it came from (a setting nudged, a confirmation chirp) is an
    optional function like any other."""
    imm = states[name]["on"].get(IMMEDIATE)
    if not imm:
        return False
    rest = imm[0]["next_state"]
    return any(
        t["next_state"] == name and sname != rest
        for sname, sdef in states.items()
        for trans in sdef["on"].values()
        for t in trans
    )


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
    if ROTATE in actions:
        rot: dict[int, dict[str, str]] = {}
        if draws[0] < 0.25:
            rot[0] = _DIR_SWAP
        if rot:
            variation[ROTATE] = rot
    presses = {tuple(p) for a, p in uses if a == PRESS}
    if actions == {PRESS} and presses == {("0",)} and draws[2] < 0.2:
        variation[PRESS] = {0: _PRESS_SWAP}  # this instance needs a long press
    if actions & {PUSH, PULL}:
        dirs = {p[0] for a, p in uses if a in (PUSH, PULL) and p}
        if dirs and dirs <= {"0", "1", "2", "3"}:
            if draws[3] < 0.25:
                mapping = _PUSH_TURN
            elif draws[3] < 0.4:
                mapping = _PUSH_FLIP_V if dirs & {"0", "1"} else _PUSH_FLIP_H
            else:
                mapping = None
            if mapping is not None:
                variation[PUSH] = {0: mapping}
                variation[PULL] = {0: mapping}
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
