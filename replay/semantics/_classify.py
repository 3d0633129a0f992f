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

        hits: list[str] = []
        if coord is not None and kind != SWITCH_VIEW:
            px, py = coord
            for comp, r in m.component_rects.get(v0, ()):
                if r[0] <= px <= r[2] and r[1] <= py <= r[3] and (not hits or hits[-1] != comp):
                    hits.append(comp)

        hit_component = hit_target = None
        distance = None
        weight = None
        nearest = None
        if is_interaction:
            px, py = coord  # type: ignore[misc]
            hit_component = bool(hits)
            rects = target_rects(m, s0, goal, v0)
            hit_target = False
            best: tuple[float, str] | None = None
            for comp, r in rects:
                d = rect_distance(r, px, py)
                if d == 0.0:
                    hit_target = True
                if best is None or (d, comp) < best:
                    best = (d, comp)
            if best is not None:
                distance, nearest = best
                fkey = (goal_index, nearest)
                weight = 1 + self._failures.get(fkey, 0)
                if not progress:
                    self._failures[fkey] = weight

        error_type = error_detail = switch_class = None
        if action is None:
            error_type, error_detail = "action_error", parsed.detail
        elif kind == SWITCH_VIEW:
            if not outcome.switched:
                error_type, error_detail = "action_error", outcome.detail
            else:
                switch_class = self._switch_class(s0, goal, v0, after.view)
                if switch_class == "NN":
                    error_type = "switch_view_nn"
                elif switch_class == "PN":
                    error_type = "switch_view_pn"
        elif kind == TIMED_WAIT:
            if outcome.kind == FB_WAIT_NO_EFFECT:
                error_type, error_detail = "invalid_waiting", "no_effect"
        elif outcome.kind == FB_INVALID:
            if outcome.detail == "out_of_range":
                error_type, error_detail = "invalid_coord", "out_of_range"
            else:
                error_type, error_detail = "action_error", outcome.detail
        elif outcome.kind != FB_UNLOCKED and not progress:
            error_type, error_detail = self._interaction_error(
                s0, goal, v0, action, hits, hit_target
            )

        repetitive = False
        if action is not None and kind != SWITCH_VIEW:
            if coord is None:
                where: tuple = ()
            elif hits:
                where = ("c",) + tuple(sorted(set(hits)))
            else:
                where = ("p", floor(coord[0] / 10 + 0.5), floor(coord[1] / 10 + 0.5))
            key = (goal_index, s0, kind, where, action.params, v0)
            if key in self._seen:
                repetitive = True
            else:
                self._seen.add(key)

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
