"""The pure step function (PROTOCOL §3): (machine, sim state, parsed action) -> (sim state, outcome).

No clock, no randomness, no I/O. Goals, budgets and scoring are layered on top of the
outcome elsewhere (`_episode.py`, `_classify.py`).
"""

from __future__ import annotations

from typing import NamedTuple

import msgspec

from . import _feedback as fb
from ._machine import CompiledTransition, Machine
from ._parse import ParsedAction
from ._vocab import (
    DASHBOARD,
    FB_INVALID,
    FB_NULL,
    FB_OPERATIONAL,
    FB_SWITCHED,
    FB_TRANSITION,
    FB_UNLOCKED,
    FB_WAIT_NO_EFFECT,
    INVALID_DETAILS,
    ORTHOGRAPHIC_VIEWS,
    SCALE,
    SWITCH_VIEW,
    TIMED_WAIT,
)


class SimState(NamedTuple):
    """What the simulator knows between steps."""

    state: int  # index into machine.states
    view: str
    unlocked: bool  # dashboard unlocked (meaningless without a dashboard)


class Outcome(msgspec.Struct, frozen=True):
    """What one step did; everything scoring needs from the simulator."""

    kind: str  # PROTOCOL §3 feedback kind
    text: str
    detail: str | None = None  # invalid_action reason
    transition: CompiledTransition | None = None
    entered: tuple[int, ...] = ()  # states entered, transient ones included
    dangerous: bool = False
    switched: bool = False  # a successful Switch_view
    unlocked_now: bool = False  # this step unlocked the dashboard (actively or passively)


def reset(
    machine: Machine, initial_state: int, initial_view: str
) -> tuple[SimState, tuple[int, ...]]:
    """Start state (after its immediate chain, if any) and the states visited getting there."""
    chain = machine.immediate_chain[initial_state]
    start = machine.chain_end[initial_state]
    return SimState(start, initial_view, False), (initial_state,) + chain


def _invalid(detail: str) -> Outcome:
    return Outcome(FB_INVALID, fb.invalid_text(detail), detail)


_INVALID = {d: _invalid(d) for d in INVALID_DETAILS}
_OPERATIONAL = Outcome(FB_OPERATIONAL, fb.OPERATIONAL_TEXT)
_NULL = Outcome(FB_NULL, fb.NULL_TEXT)
_WAIT_NO_EFFECT = Outcome(FB_WAIT_NO_EFFECT, fb.WAIT_NO_EFFECT_TEXT)
_PASSIVE = Outcome(FB_UNLOCKED, fb.UNLOCKED_TEXT, unlocked_now=True)


def step(machine: Machine, sim: SimState, parsed: ParsedAction) -> tuple[SimState, Outcome]:
    """Apply one agent response to the device."""
    if not parsed.ok or parsed.action is None:
        return sim, _INVALID.get(parsed.detail or "malformed", _INVALID["malformed"])
    action = parsed.action
    kind = action.type

    if kind == SWITCH_VIEW:
        if len(action.params) != 1 or action.params[0] not in machine.views:
            return sim, _INVALID["invalid_view"]
        view = action.params[0]
        if view == DASHBOARD and not sim.unlocked:
            coord = action.coord
            if coord is not None and machine.in_dashboard_region(sim.view, coord[0], coord[1]):
                new = SimState(sim.state, DASHBOARD, True)
                return new, Outcome(
                    FB_SWITCHED, fb.switched_text(DASHBOARD, True), switched=True, unlocked_now=True
                )
            return sim, _INVALID["locked_dashboard"]
        return SimState(sim.state, view, sim.unlocked), Outcome(
            FB_SWITCHED, fb.switched_text(view, False), switched=True
        )

    if kind == TIMED_WAIT:
        tr = machine.wait[sim.state]
        if tr is None:
            return sim, _WAIT_NO_EFFECT
        return apply_transition(machine, sim, tr)

    # Interactions: Press / Rotate / Push / Pull / Grasp.
    view = sim.view
    if view not in ORTHOGRAPHIC_VIEWS and view != DASHBOARD:
        return sim, _INVALID["axonometric_view"]
    coord = action.coord
    if coord is None:
        return sim, _INVALID["missing_coord"]
    px, py = coord
    if not (0.0 <= px <= SCALE and 0.0 <= py <= SCALE):
        return sim, _INVALID["out_of_range"]
    if not sim.unlocked and machine.dashboard_regions and machine.in_dashboard_region(view, px, py):
        return SimState(sim.state, view, True), _PASSIVE

    best: CompiledTransition | None = None
    best_key: tuple | None = None
    hit = False
    params = action.params
    for tr, rects in machine.by_state_view.get((sim.state, view), ()):
        area = None
        for r in rects:
            if r[0] <= px <= r[2] and r[1] <= py <= r[3] and (area is None or r[4] < area):
                area = r[4]
        if area is None:
            continue
        hit = True
        if tr.action == kind and tr.params_match(params):
            key = (area, tr.component, tr.index)
            if best_key is None or key < best_key:
                best, best_key = tr, key
    if best is not None:
        return apply_transition(machine, sim, best)
    return sim, (_OPERATIONAL if hit else _NULL)


def apply_transition(
    machine: Machine, sim: SimState, tr: CompiledTransition
) -> tuple[SimState, Outcome]:
    """Fire `tr` from `sim` (PROTOCOL §3.3, §3.4): the device moves to the stable end of the
    transition's chain and the feedback is the transition's text (the texts of the error
    states it enters appended when it is dangerous). The view and the dashboard stay."""
    text = tr.description
    if tr.dangerous:
        errors = [machine.descriptions[s] for s in tr.entered if s in machine.error_states]
        text = ". ".join([text.strip().rstrip(".")] + [e.strip().rstrip(".") for e in errors])
    outcome = Outcome(
        FB_TRANSITION,
        fb.transition_text(text, machine.descriptions[tr.end]),
        transition=tr,
        entered=tr.entered,
        dangerous=tr.dangerous,
    )
    return SimState(tr.end, sim.view, sim.unlocked), outcome
