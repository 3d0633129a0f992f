"""Step classification (PROTOCOL §5), computed from simulator outcomes and the planner.

Kept apart from the simulator: it reads (state before, parsed action, outcome, state after)
and never changes the device. One `Classifier` per episode holds the little history PROTOCOL §5
needs (repetition keys, failed attempts per nearest target).
"""

from __future__ import annotations

from math import floor

from ._machine import Machine, rect_distance
from ._parse import ParsedAction
from ._plan import INF, distances, progressing, target_components, target_rects
from ._step import Outcome, SimState
from ._vocab import (
    DASHBOARD,
    ERROR_GROUPS,
    FB_INVALID,
    FB_TRANSITION,
    FB_UNLOCKED,
    FB_WAIT_NO_EFFECT,
    INTERACTIONS,
    ORTHOGRAPHIC_VIEWS,
    SWITCH_VIEW,
    TIMED_WAIT,
)

_INTERACTIONS = frozenset(INTERACTIONS)


Classification = tuple
"""The values of `CLASSIFICATION_FIELDS` (replay._rows), in that order: a plain tuple
because the replay loop splices it straight into the step row."""


_SWITCH_ERRORS = {"NN": "switch_view_nn", "PN": "switch_view_pn"}
"""The error type of a successful switch, by its class (NP and PP are no error)."""


def _where(coord: tuple[float, float] | None, hits: list[str]) -> tuple:
    """Where a step acted, for its repetition key: nowhere, the components hit, or the cell
    of a 10-point grid holding the point."""
    if coord is None:
        return ()
    if hits:
        return ("c",) + tuple(sorted(set(hits)))
    return ("p", floor(coord[0] / 10 + 0.5), floor(coord[1] / 10 + 0.5))


class Classifier:
    """Classifies the steps of one episode, in order."""

    def __init__(self, machine: Machine) -> None:
        self.m = machine
        self._seen: set[tuple] = set()
        self._failures: dict[tuple[int, str], int] = {}
        self._goal = -1
        self._dist: tuple[int, ...] = ()

    def classify(
        self,
        goal_index: int,
        goal: int,
        before: SimState,
        parsed: ParsedAction,
        outcome: Outcome,
        after: SimState,
        completed: int,
    ) -> Classification:
        m = self.m
        action = parsed.action if parsed.ok else None
        kind = action.type if action is not None else None
        s0, v0 = before.state, before.view
        if goal != self._goal:
            self._goal, self._dist = goal, distances(m, goal)
        dist = self._dist
        d_before = dist[s0]
        d_after = dist[after.state]
        progress = completed > 0 or d_after < d_before

        coord = action.coord if action is not None else None
        is_interaction = (
            kind in _INTERACTIONS
            and coord is not None
            and (v0 in ORTHOGRAPHIC_VIEWS or v0 == DASHBOARD)
            and outcome.kind != FB_UNLOCKED
        )
        hits = self._hits(v0, coord) if coord is not None and kind != SWITCH_VIEW else []
        hit_component = hit_target = distance = weight = nearest = None
        if is_interaction:
            hit_component = bool(hits)
            hit_target, distance, nearest = self._nearest_target(s0, goal, v0, coord)
            if nearest is not None:
                fkey = (goal_index, nearest)
                weight = 1 + self._failures.get(fkey, 0)
                if not progress:
                    self._failures[fkey] = weight
        error_type, error_detail, switch_class = self._error(
            s0, goal, before, after, parsed, outcome, progress, hits, hit_target
        )
        repetitive = action is not None and kind != SWITCH_VIEW and self._repeated(
            (goal_index, s0, kind, _where(coord, hits), action.params, v0)
        )
        if kind == SWITCH_VIEW:
            eer_valid = None
        elif action is None:
            eer_valid = False
        else:
            eer_valid = (
                (outcome.kind == FB_TRANSITION or outcome.unlocked_now)
                and not outcome.dangerous
                and not repetitive
            )

        return (
            is_interaction,
            hit_component,
            hit_target,
            sorted(set(hits)) if len(hits) > 1 else hits,
            nearest,
            progress,
            None if d_before >= INF else d_before,
            None if d_after >= INF else d_after,
            error_type,
            error_detail,
            ERROR_GROUPS.get(error_type) if error_type else None,
            switch_class,
            repetitive,
            eer_valid,
            distance,
            weight,
        )

    def _hits(self, view: str, coord: tuple[float, float]) -> list[str]:
        """The components whose boxes in `view` hold the point, in box order, each run of
        the same component once."""
        px, py = coord
        hits: list[str] = []
        for comp, r in self.m.component_rects.get(view, ()):
            if r[0] <= px <= r[2] and r[1] <= py <= r[3] and (not hits or hits[-1] != comp):
                hits.append(comp)
        return hits

    def _nearest_target(
        self, s: int, goal: int, view: str, coord: tuple[float, float]
    ) -> tuple[bool, float | None, str | None]:
        """(a target's box holds the point, the distance to the nearest target box, its
        component): ties go to the component first by name."""
        px, py = coord
        hit_target = False
        best: tuple[float, str] | None = None
        for comp, r in target_rects(self.m, s, goal, view):
            d = rect_distance(r, px, py)
            if d == 0.0:
                hit_target = True
            if best is None or (d, comp) < best:
                best = (d, comp)
        return (hit_target, *best) if best is not None else (hit_target, None, None)

    def _error(
        self,
        s0: int,
        goal: int,
        before: SimState,
        after: SimState,
        parsed: ParsedAction,
        outcome: Outcome,
        progress: bool,
        hits: list[str],
        hit_target: bool | None,
    ) -> tuple[str | None, str | None, str | None]:
        """(error type, its detail, the switch class) of a step (PROTOCOL §5.2)."""
        action = parsed.action if parsed.ok else None
        if action is None:
            return "action_error", parsed.detail, None
        kind = action.type
        if kind == SWITCH_VIEW:
            if not outcome.switched:
                return "action_error", outcome.detail, None
            switch_class = self._switch_class(s0, goal, before.view, after.view)
            return _SWITCH_ERRORS.get(switch_class), None, switch_class
        if kind == TIMED_WAIT:
            if outcome.kind == FB_WAIT_NO_EFFECT:
                return "invalid_waiting", "no_effect", None
            return None, None, None
        if outcome.kind == FB_INVALID:
            if outcome.detail == "out_of_range":
                return "invalid_coord", "out_of_range", None
            return "action_error", outcome.detail, None
        if outcome.kind != FB_UNLOCKED and not progress:
            return (*self._interaction_error(s0, goal, before.view, action, hits, hit_target), None)
        return None, None, None

    def _repeated(self, key: tuple) -> bool:
        """The key was seen before in this episode (and is remembered from now on)."""
        if key in self._seen:
            return True
        self._seen.add(key)
        return False

    def _switch_class(self, s: int, goal: int, start: str, end: str) -> str | None:
        targets = target_components(self.m, s, goal)
        if not targets:
            return None
        scr = self.m.state_component_rects

        def positive(view: str) -> str:
            comps = scr.get((s, view), {})
            return "P" if any(c in targets for c in comps) else "N"

        return positive(start) + positive(end)

    def _interaction_error(
        self, s: int, goal: int, view: str, action, hits: list[str], hit_target: bool | None
    ) -> tuple[str, str | None]:
        if not hits:
            return "invalid_coord", None
        if not hit_target:
            return "component_selection", None
        px, py = action.coord
        candidates = [
            tr
            for tr in progressing(self.m, s, goal)
            if tr.action is not None
            and any(r[0] <= px <= r[2] and r[1] <= py <= r[3] for r in tr.rects.get(view, ()))
        ]
        same_type = [tr for tr in candidates if tr.action == action.type]
        if not same_type:
            return "action_error", "wrong_action"
        if not any(tr.params_match(action.params) for tr in same_type):
            return "params_error", None
        return "component_selection", None
