"""A simulated agent: plays one task through the pure simulator (`replay.reset`/`replay.step`)
and returns the log steps (PROTOCOL §1.4).

The agent knows, as a simulation, which transitions make progress (`replay.semantics.progressing`),
and a `Profile` decides how often it acts on that knowledge: whether it finds the view that
shows the target, picks the right component, action and parameters, aims well, waits when
a process runs, keeps to the output format, and remembers within its history window what
failed (so it does not repeat it, corrects its aim, and changes its action after an
'operational_error'). It plays until the episode terminates under the lambda budgets
(PROTOCOL §3), so a replay of its log ends exactly at the last step.
"""

from __future__ import annotations

import random
from collections import deque
from dataclasses import dataclass

import replay
from replay import AXONOMETRIC_VIEWS, DASHBOARD, INTERACTIONS, SCALE
from replay.semantics import (
    FB_INVALID,
    FB_NULL,
    FB_OPERATIONAL,
    FB_TRANSITION,
    FRONT,
    GRASP,
    PRESS,
    PULL,
    PUSH,
    ROTATE,
    SWITCH_VIEW,
    TIMED_WAIT,
)

from ._catalog import Catalog, ComponentSpec
from ._profiles import Profile
from ._tasks import TaskRecord
from ._thinking import (
    describe,
    intent_text,
    verb_phrase,
)

RESAMPLE = 0.02
"""Chance that the agent reconsiders a standing belief without feedback telling it to."""
STALE_STATE = 0.85
"""Without history: chance of planning from the state the goal started in, not the current one."""
KIND_ACTIONS: dict[str, tuple[str, ...]] = {
    "button": (PRESS, PUSH),
    "touch_pad": (PRESS,),
    "key": (PRESS,),
    "trigger": (PRESS, PULL),
    "shutter_button": (PRESS,),
    "knob": (ROTATE, PRESS, PULL, PUSH),
    "dial": (ROTATE, PRESS),
    "wheel": (ROTATE, PUSH),
    "ring": (ROTATE,),
    "crank": (ROTATE,),
    "lens": (ROTATE, PUSH, PULL),
    "slider": (PUSH, PULL),
    "switch": (PUSH, PRESS),
    "rocker": (PRESS, PUSH),
    "lever": (PUSH, PULL, PRESS),
    "door": (PULL, PUSH),
    "lid": (PULL, PUSH, PRESS),
    "cover": (PULL, PUSH),
    "drawer": (PULL, PUSH),
    "basket": (PULL, PUSH),
    "tank": (PULL, PUSH),
    "tray": (PULL, PUSH),
    "cap": (PULL, PUSH, ROTATE),
    "head": (PULL, PUSH, ROTATE),
    "nozzle": (PULL, PUSH, ROTATE),
    "attachment": (PULL, PUSH),
    "port": (PUSH, PULL),
    "plug": (PUSH, PULL),
    "cable": (PUSH, PULL),
    "handle": (GRASP, PULL, PUSH),
    "grip": (GRASP, PRESS),
    "handset": (GRASP, PULL),
    "body": (GRASP, PRESS),
    "platform": (PRESS, PUSH),
    "blade": (PULL, PUSH),
}


@dataclass(frozen=True, slots=True)
class Decision:
    """What the agent does at one step (before formatting)."""

    action: replay.Action
    thinking: str
    component: str | None = None
    """The component the agent means to operate (None: a view switch, a wait, empty space)."""


@dataclass(slots=True)
class _Event:
    step: int
    goal_index: int
    state: int
    view: str
    component: str | None
    action: replay.Action
    kind: str
    progress: bool
    moved_away: bool


@dataclass(frozen=True, slots=True)
class AgentStep:
    """One logged step with what the simulator did (for the recorded fields)."""

    decision: Decision
    output: str | None
    record: dict | None
    outcome: replay.Outcome
    view: str
    state: str


class Agent:
    """The policy of one profile on one episode."""

    def __init__(
        self,
        machine: replay.Machine,
        catalog: Catalog,
        profile: Profile,
        task: TaskRecord,
        rng: random.Random,
    ) -> None:
        self.m = machine
        self.catalog = catalog
        self.p = profile
        self.task = task
        self.rng = rng
        self.events: deque[_Event] = deque()
        self.step_index = 0
        self.regions = tuple(v for v in machine.views if v in machine.dashboard_regions)
        self.beliefs: dict[tuple[int, int], str | None] = {}
        self.insight: dict[int, bool] = {}
        self.segment_start: dict[int, int] = {}
        self.operations: dict[tuple[int, int, str], replay.Action] = {}
        self.switch_views = tuple(v for v in machine.views if v != DASHBOARD)

    # ------------------------------------------------------------------ memory

    def _recent(self) -> list[_Event]:
        h = self.p.history_length
        if h is None:
            return list(self.events)
        if h <= 0:
            return []
        return [e for e in self.events if e.step >= self.step_index - h]

    def _remembers(self) -> bool:
        return self.rng.random() < self.p.memory

    def _failed(
        self, recent: list[_Event], state: int, comp: str | None, action: replay.Action
    ) -> bool:
        for e in recent:
            if (
                e.state == state
                and e.component == comp
                and e.action.type == action.type
                and e.action.params == action.params
                and not e.progress
                and e.kind in (FB_NULL, FB_OPERATIONAL, FB_TRANSITION, FB_INVALID)
            ):
                return True
        return False

    def _misses(self, recent: list[_Event], comp: str) -> int:
        return sum(1 for e in recent if e.component == comp and e.kind == FB_NULL)

    def _refuted(self, recent: list[_Event], state: int, goal_index: int) -> set[str]:
        """Components the agent has given up on for this goal in this state: they did the
        wrong thing, or several attempts at them achieved nothing."""
        fails: dict[str, int] = {}
        out: set[str] = set()
        for e in recent:
            if e.component is None or e.state != state or e.goal_index != goal_index:
                continue
            if e.moved_away or (e.kind == FB_TRANSITION and not e.progress):
                out.add(e.component)
            elif e.kind in (FB_NULL, FB_OPERATIONAL) and not e.progress:
                fails[e.component] = fails.get(e.component, 0) + 1
                if fails[e.component] >= 3:
                    out.add(e.component)
        return out

    # ------------------------------------------------------------------ helpers

    def _spec(self, comp: str | None):
        return self.catalog.components.get(comp) if comp else None

    def _rects_in(self, state: int, view: str, comp: str) -> tuple:
        per = self.m.state_component_rects.get((state, view), {})
        if comp in per:
            return per[comp]
        return tuple(r for c, r in self.m.component_rects.get(view, ()) if c == comp)

    def _visible_components(self, view: str) -> list[str]:
        seen: dict[str, None] = {}
        for c, _ in self.m.component_rects.get(view, ()):
            seen.setdefault(c, None)
        return list(seen)

    def _aim(self, rect: tuple, misses: int) -> tuple[float, float]:
        rng = self.rng
        if rng.random() < self.p.gross_miss * (self.p.reground**misses):
            return float(rng.randint(40, 960)), float(rng.randint(40, 960))
        cx = (rect[0] + rect[2]) / 2.0
        cy = (rect[1] + rect[3]) / 2.0
        sigma = self.p.sigma * (self.p.reground**misses)
        x = cx + rng.gauss(0.0, sigma)
        y = cy + rng.gauss(0.0, sigma)
        return float(min(SCALE, max(0, round(x)))), float(min(SCALE, max(0, round(y))))

    def _aimed(
        self,
        operation: replay.Action,
        spec: ComponentSpec | None,
        rect: tuple,
        view: str,
        recent: list[_Event],
        comp: str,
        remember: bool,
    ) -> tuple[replay.Action, str, int]:
        """`operation` aimed at `rect` (an agent that remembers its misses on `comp` aims
        with their spread), how the agent names that place, and the misses counted."""
        misses = self._misses(recent, comp) if remember else 0
        action = replay.Action(operation.type, self._aim(rect, misses), operation.params)
        return action, describe(spec, rect, view), misses

    def _params_for(self, action_type: str, rng: random.Random) -> tuple[str, ...]:
        if action_type == PRESS:
            return (rng.choice(("0", "0", "0", "1", "2")),)
        if action_type == ROTATE:
            return (rng.choice(("0", "1")), str(rng.choice((1, 1, 2, 3, 4))))
        if action_type in (PUSH, PULL):
            return (rng.choice(("0", "1", "2", "3", "4")),)
        if action_type == GRASP:
            return (rng.choice(("0", "0", "1")),)
        return ()

    @staticmethod
    def _concrete(tr: replay.semantics.CompiledTransition, rng: random.Random) -> tuple[str, ...]:
        if not tr.params:
            return ("0",) if tr.action in (PRESS, GRASP) else ()
        out = []
        for i, p in enumerate(tr.params):
            if p != "*":
                out.append(p)
            elif tr.action == ROTATE and i == 1:
                out.append(str(rng.choice((1, 2, 3))))
            else:
                out.append("0")
        return tuple(out)

    # ------------------------------------------------------------------ deciding

    def decide(self, sim: replay.SimState, goal_index: int, goal: int) -> Decision:
        rng = self.rng
        p = self.p
        m = self.m
        recent = self._recent()
        s, view = sim.state, sim.view
        instruction = (
            self.task.instructions[goal_index] if goal_index < len(self.task.instructions) else ""
        )
        intent = intent_text(instruction)
        start = self.segment_start.setdefault(goal_index, s)
        plan_state = s
        if p.history_length == 0 and s != start and rng.random() < STALE_STATE:
            # Without any history the agent cannot tell that its last action changed the
            # device (the pictures look the same): it plans from where the goal began.
            plan_state = start
        targets = replay.semantics.progressing(m, plan_state, goal)
        real = [t for t in targets if t.action is not None]
        waited = self._wait(intent, real, any(t.action is None for t in targets))
        if waited is not None:
            return waited
        if view in AXONOMETRIC_VIEWS:
            return self._in_overview(sim, goal_index, real, recent, intent)

        visible = [t for t in real if view in t.rects]
        if not visible:
            comps_here = self._visible_components(view)
            if comps_here and rng.random() < p.explore_here:
                return self._interact_wrong(sim, goal_index, comps_here, recent, intent)
            return self._navigate(sim, goal_index, real, recent, intent, reason="missing")

        if rng.random() < p.wander:
            options = [v for v in self.switch_views if v != view]
            target = rng.choice(options)
            return Decision(
                replay.Action(SWITCH_VIEW, None, (target,)),
                f"{intent} Before acting I want to check the {target.replace('_', ' ')} view "
                "for other controls.",
            )

        refined = self._refine(sim, goal_index, visible, recent, intent)
        if refined is not None:
            return refined
        comp = self._hypothesis(sim, goal_index, visible, recent)
        same = [t for t in visible if t.component == comp]
        if same:
            return self._interact(sim, goal_index, rng.choice(same), recent, intent)
        if comp is None:
            return self._interact_empty(sim, intent)
        return self._interact_component(sim, goal_index, comp, recent, intent)

    def _wait(self, intent: str, real: list, wait_needed: bool) -> Decision | None:
        """A timed wait when the goal needs one and the profile knows it (or, by mistake,
        when it does not), else None."""
        rng, p = self.rng, self.p
        if wait_needed and (not real or rng.random() < 0.75):
            if rng.random() < p.wait_knowledge:
                return Decision(
                    replay.Action(TIMED_WAIT),
                    f"{intent} The {self.catalog.device_noun} is still working; the process "
                    "needs time to finish, so I will wait for it to complete.",
                )
        elif not wait_needed and rng.random() < p.spurious_wait:
            return Decision(
                replay.Action(TIMED_WAIT),
                f"{intent} The {self.catalog.device_noun} may need a moment to respond to the "
                "last operation. I will wait.",
            )
        return None

    def _in_overview(
        self,
        sim: replay.SimState,
        goal_index: int,
        real: list,
        recent: list[_Event],
        intent: str,
    ) -> Decision:
        """In an axonometric view: a press there by mistake (unless the agent remembers that
        it fails), else a switch to a view where the target is."""
        rng, p, s, view = self.rng, self.p, sim.state, sim.view
        axo_seen = any(
            e.kind == FB_INVALID and e.view == view and e.action.type in INTERACTIONS
            for e in recent
        )
        if rng.random() < p.axo_mistake and not (axo_seen and self._remembers()):
            comps = self._visible_components(FRONT)
            rect = None
            comp = None
            if real and rng.random() < 0.5:
                tr = rng.choice(real)
                comp = tr.component
                rects = self._rects_in(s, next(iter(tr.rects)), comp)
                rect = rects[0] if rects else None
            elif comps:
                comp = rng.choice(comps)
                rects = self._rects_in(s, FRONT, comp)
                rect = rects[0] if rects else None
            point = self._aim(rect, 0) if rect else (500.0, 500.0)
            action = replay.Action(PRESS, point, ("0",))
            text = (
                f"{intent} In this overview I can see {describe(self._spec(comp), None, view)}. "
                f"I will {verb_phrase(action)}."
            )
            return Decision(action, text, comp)
        return self._navigate(sim, goal_index, real, recent, intent, reason="axonometric")

    def _refine(
        self,
        sim: replay.SimState,
        goal_index: int,
        visible: list,
        recent: list[_Event],
        intent: str,
    ) -> Decision | None:
        """Hypothesis refinement: the last attempt hit the right component the wrong way, and
        the profile uses that feedback; else None."""
        last = recent[-1] if recent else None
        if (
            last is not None
            and last.kind == FB_OPERATIONAL
            and last.state == sim.state
            and last.view == sim.view
            and last.component is not None
            and self.rng.random() < self.p.feedback_use
        ):
            comp = last.component
            self.beliefs[(goal_index, sim.state)] = comp
            same = [t for t in visible if t.component == comp]
            if same:
                return self._interact(
                    sim, goal_index, self.rng.choice(same), recent, intent, refine=True
                )
            return self._interact_component(sim, goal_index, comp, recent, intent, refine=True)
        return None

    def _hypothesis(
        self, sim: replay.SimState, goal_index: int, visible: list, recent: list[_Event]
    ) -> str | None:
        """The component the agent believes does the job. A belief persists (within the
        history window) until feedback refutes it; each refuted guess makes the right one
        likelier, as elimination does."""
        rng = self.rng
        s, view = sim.state, sim.view
        key = (goal_index, s)
        refuted = self._refuted(recent, s, goal_index) if self._remembers() else set()
        here = self._visible_components(view)
        targets = sorted({t.component for t in visible})
        belief = self.beliefs.get(key)
        # A model given the same picture and instruction mostly answers the same way: a
        # belief stands until remembered feedback refutes it (or, now and then, on a whim).
        keep = key in self.beliefs and rng.random() >= RESAMPLE
        if keep and belief not in refuted and (belief is None or belief in here):
            return belief
        wrong = [c for c in here if c not in targets and c not in refuted]
        insight = self.insight.get(goal_index)
        if insight is None:
            # Whether the agent recognises what to operate for this goal at all: the paper's
            # agents either solve a goal fairly directly or flounder.
            insight = rng.random() < self.p.component_knowledge
            self.insight[goal_index] = insight
        if not refuted and key not in self.beliefs:
            knowledge = 0.95 if insight else 0.15
        else:
            knowledge = min(0.9, 0.5 * self.p.component_knowledge + 0.1 * len(refuted))
        if not wrong or rng.random() < knowledge:
            fresh = [c for c in targets if c not in refuted] or targets
            belief = rng.choice(fresh)
        elif rng.random() < 0.12:
            belief = None  # something that looks like a control but is not one
        else:
            belief = rng.choice(wrong)
        self.beliefs[key] = belief
        return belief

    def _navigate(
        self,
        sim: replay.SimState,
        goal_index: int,
        real: list,
        recent: list[_Event],
        intent: str,
        reason: str,
    ) -> Decision:
        rng = self.rng
        p = self.p
        view = sim.view
        target_views = sorted(
            {w for t in real for w in t.rects if w not in AXONOMETRIC_VIEWS},
            key=lambda w: replay.VIEW_ORDER.index(w) if w in replay.VIEW_ORDER else 99,
        )
        here = view.replace("_", " ")
        lead = (
            f"{intent} This is an angled overview; I cannot operate anything from here."
            if reason == "axonometric"
            else f"{intent} I cannot find a control for this in the {here} view."
        )
        if target_views and set(target_views) == {DASHBOARD} and not sim.unlocked:
            if view in self.regions:
                region = self.m.dashboard_regions[view][0]
                x = rng.random()
                failed_plain = any(
                    e.kind == FB_INVALID
                    and e.action.type == SWITCH_VIEW
                    and e.action.coord is None
                    and e.action.params == (DASHBOARD,)
                    for e in recent
                )
                skill = p.dashboard_skill
                if failed_plain and self._remembers():
                    skill = max(skill, 0.9)
                point = self._aim(region, 2)
                if x < skill:
                    return Decision(
                        replay.Action(SWITCH_VIEW, point, (DASHBOARD,)),
                        f"{intent} The control panel is too small to read from here. I will zoom in "
                        "on it by switching to the dashboard view at the panel.",
                    )
                if x < skill + (1.0 - skill) / 2.0:
                    action = replay.Action(PRESS, point, ("0",))
                    return Decision(
                        action,
                        f"{intent} The control I need should be on the small panel "
                        f"{_where(region)}. I will press it.",
                    )
                return Decision(
                    replay.Action(SWITCH_VIEW, None, (DASHBOARD,)),
                    f"{intent} The controls are tiny; I will switch to the dashboard view.",
                )
            if rng.random() < p.nav_skill:
                target = self.regions[0]
            else:
                target = self._random_view(view, recent, goal_index)
            return self._switch(target, lead)
        options = [w for w in target_views if w != DASHBOARD or sim.unlocked]
        if options and rng.random() < p.nav_skill:
            target = rng.choice(options)
        else:
            target = self._random_view(view, recent, goal_index)
        return self._switch(target, lead)

    def _random_view(self, view: str, recent: list[_Event], goal_index: int) -> str:
        rng = self.rng
        options = [v for v in self.switch_views if v != view]
        if self._remembers():
            tried = {e.view for e in recent if e.goal_index == goal_index}
            fresh = [v for v in options if v not in tried]
            if fresh:
                options = fresh
        return rng.choice(options)

    def _switch(self, target: str, lead: str) -> Decision:
        hint = (
            "Its panel should be visible there."
            if target == DASHBOARD
            else f"The control may be on the {target.replace('_', ' ')} side."
        )
        return Decision(
            replay.Action(SWITCH_VIEW, None, (target,)),
            f"{lead} {hint} I will switch to the {target.replace('_', ' ')} view.",
        )

    def _interact(
        self,
        sim: replay.SimState,
        goal_index: int,
        tr: replay.semantics.CompiledTransition,
        recent: list[_Event],
        intent: str,
        refine: bool = False,
    ) -> Decision:
        """Operate a target component, with the profile's action and parameter knowledge."""
        rng = self.rng
        p = self.p
        comp = tr.component
        correct = replay.Action(tr.action, None, self._concrete(tr, rng))
        spec = self._spec(comp)
        kinds = KIND_ACTIONS.get(spec.kind, INTERACTIONS) if spec else INTERACTIONS
        remember = self._remembers()
        key = (goal_index, sim.state, comp)
        chosen = self.operations.get(key)
        if chosen is not None and (remember and self._failed(recent, sim.state, comp, chosen)):
            chosen = None
        if chosen is not None and rng.random() < RESAMPLE:
            chosen = None
        if chosen is None:
            for _ in range(6):
                if rng.random() < p.action_knowledge:
                    a_type = correct.type
                else:
                    others = [a for a in kinds if a != correct.type] or [
                        a for a in INTERACTIONS if a != correct.type
                    ]
                    a_type = rng.choice(others)
                if a_type == correct.type and rng.random() < p.param_knowledge:
                    params = correct.params
                else:
                    params = self._params_for(a_type, rng)
                cand = replay.Action(a_type, None, params)
                if remember and self._failed(recent, sim.state, comp, cand):
                    continue
                chosen = cand
                break
            if chosen is None:
                chosen = (
                    correct
                    if rng.random() < 0.5
                    else replay.Action(
                        rng.choice(kinds), None, self._params_for(rng.choice(kinds), rng)
                    )
                )
            self.operations[key] = chosen
        action, where, misses = self._aimed(
            chosen, spec, tr.rects[sim.view][0], sim.view, recent, comp, remember
        )
        if refine:
            text = (
                f"{intent} The last attempt on {where} showed it can be operated, but not in "
                f"that way. I will try to {verb_phrase(action)} instead."
            )
        elif misses:
            text = (
                f"{intent} My previous click seems to have missed {where}. I will aim more "
                f"carefully and {verb_phrase(action)}."
            )
        else:
            text = f"{intent} I can see {where}; it looks like the right control. I will {verb_phrase(action)}."
        return Decision(action, text, comp)

    def _interact_component(
        self,
        sim: replay.SimState,
        goal_index: int,
        comp: str,
        recent: list[_Event],
        intent: str,
        refine: bool = False,
    ) -> Decision:
        """Operate a (non-target) component by guessing its action from its look."""
        rng = self.rng
        spec = self._spec(comp)
        kinds = KIND_ACTIONS.get(spec.kind, INTERACTIONS) if spec else INTERACTIONS
        remember = self._remembers()
        cand = None
        for _ in range(6):
            a_type = kinds[0] if rng.random() < 0.6 else rng.choice(kinds)
            cand = replay.Action(a_type, None, self._params_for(a_type, rng))
            if not (remember and self._failed(recent, sim.state, comp, cand)):
                break
        assert cand is not None
        rects = self._rects_in(sim.state, sim.view, comp)
        if not rects:
            return self._interact_empty(sim, intent)
        action, where, _ = self._aimed(cand, spec, rects[0], sim.view, recent, comp, remember)
        if refine:
            text = (
                f"{intent} {where[0].upper() + where[1:]} reacted but not in that way. "
                f"I will try to {verb_phrase(action)}."
            )
        else:
            text = f"{intent} I think {where} might control this. I will {verb_phrase(action)}."
        return Decision(action, text, comp)

    def _interact_wrong(
        self,
        sim: replay.SimState,
        goal_index: int,
        comps: list[str],
        recent: list[_Event],
        intent: str,
    ) -> Decision:
        rng = self.rng
        if comps and rng.random() < 0.8:
            return self._interact_component(sim, goal_index, rng.choice(comps), recent, intent)
        return self._interact_empty(sim, intent)

    def _interact_empty(self, sim: replay.SimState, intent: str) -> Decision:
        rng = self.rng
        point = (float(rng.randint(60, 940)), float(rng.randint(60, 940)))
        a_type = rng.choice((PRESS, PRESS, ROTATE, PUSH, PULL))
        action = replay.Action(a_type, point, self._params_for(a_type, rng))
        return Decision(
            action,
            f"{intent} There seems to be a control {_where((point[0], point[1], point[0], point[1]))}. "
            f"I will {verb_phrase(action)}.",
        )

    # ------------------------------------------------------------------ observing

    def observe(
        self,
        decision: Decision,
        parsed: replay.ParsedAction,
        before: replay.SimState,
        after: replay.SimState,
        outcome: replay.Outcome,
        goal_index: int,
        goal: int,
        completed: int,
    ) -> None:
        dist = replay.semantics.distances(self.m, goal)
        progress = completed > 0 or dist[after.state] < dist[before.state]
        moved_away = outcome.dangerous or dist[after.state] > dist[before.state]
        # A format slip says nothing about the action the agent meant.
        kind = outcome.kind if parsed.ok else "slip"
        self.events.append(
            _Event(
                self.step_index,
                goal_index,
                before.state,
                before.view,
                decision.component,
                decision.action,
                kind,
                progress,
                moved_away,
            )
        )
        self.step_index += 1


def _where(rect: tuple) -> str:
    from ._thinking import position_words

    return position_words(rect)
