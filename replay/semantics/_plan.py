"""Planning (PROTOCOL §4): distances, target components, the static joint plan and C_opt.

An optimal plan minimises (transitions, view switches) lexicographically. Because the state
after completing goal i is fixed (the immediate chain of g_i), its transition count is the
sum of per-goal distances, and only *tight* transitions (those lowering the distance) can
appear in it. Over that DAG we minimise switches jointly across goals, evaluating (goal
index, state, view, dashboard unlocked) depth first with memoisation, on a stack of our own
(never Python's: a plan is as long as the input makes it). Switches are folded into the
interaction that needs them, so they land as late as possible. PROTOCOL §4.3 lists the
tie-breaks.
"""

from __future__ import annotations

from collections.abc import Generator
from dataclasses import dataclass
from operator import add, itemgetter

from .._errors import TaskError
from ._machine import CompiledTransition, Machine, Rect, rect_contains
from ._parse import Action
from ._vocab import DASHBOARD, ORTHOGRAPHIC_VIEWS, SWITCH_VIEW, TIMED_WAIT, VIEW_ORDER, VIEW_RANK

INF = 1 << 30


# ----------------------------------------------------------------------------- distances


def distances(machine: Machine, goal: int) -> tuple[int, ...]:
    """`dist(s, goal)` for every state (PROTOCOL §4); INF when unreachable. Cached per machine.

    Immediate edges cost 0: a state with an immediate chain has the distance of the chain's
    end, or 0 when the chain passes through the goal. `dist(goal, goal) = 0`.
    """
    key = ("dist", goal)
    cached = machine._cache.get(key)
    if cached is not None:
        return cached
    graph = _graph(machine)
    dist = [INF] * len(machine.states)
    dist[goal] = 0
    frontier: list[int] = []
    for s in graph.entering.get(goal, ()):
        if dist[s] > 1:
            dist[s] = 1
            frontier.append(s)
    # Breadth first back from the states one transition away. A transition entering the goal
    # is among `before` too: its source is at 1 (or the goal) already, so it sets nothing.
    before = graph.before
    while frontier:
        nxt: list[int] = []
        for s in frontier:
            d = dist[s] + 1
            for p in before.get(s, ()):
                if dist[p] == INF:
                    dist[p] = d
                    nxt.append(p)
        frontier = nxt
    chain_end = machine.chain_end
    for s, chain in enumerate(machine.immediate_chain):
        if chain and s != goal:
            dist[s] = 0 if goal in chain else dist[chain_end[s]]
    result = tuple(dist)
    machine._cache[key] = result
    return result


class _Graph:
    """The agent's transition graph of a machine, which every goal's distances walk: built
    once per machine rather than once per goal."""

    __slots__ = ("m", "agent", "before", "entering", "options")

    def __init__(self, machine: Machine) -> None:
        self.m = machine
        self.agent: tuple[tuple[CompiledTransition, ...], ...] = tuple(
            machine.by_state[s] + ((w,) if (w := machine.wait[s]) is not None else ())
            for s in range(len(machine.states))
        )
        # the sources (stable states) of the transitions ending in a state, and entering it
        self.before: dict[int, list[int]] = {}
        self.entering: dict[int, list[int]] = {}
        for s, transitions in enumerate(self.agent):
            if machine.immediate_chain[s]:
                continue  # the agent never stands in a transient state
            for tr in transitions:
                self.before.setdefault(tr.end, []).append(s)
                for x in tr.entered:
                    self.entering.setdefault(x, []).append(s)
        self.options: dict[tuple[int, str, bool], tuple[_Option, ...]] = {}  # _state_options


def _graph(machine: Machine) -> _Graph:
    graph = machine._cache.get("graph")
    if graph is None:
        graph = machine._cache["graph"] = _Graph(machine)
    return graph


def progressing(machine: Machine, s: int, goal: int) -> tuple[CompiledTransition, ...]:
    """Transitions from `s` that complete `goal` or lower its distance (timed_wait included)."""
    key = ("prog", goal, s)
    cached = machine._cache.get(key)
    if cached is not None:
        return cached
    dist = distances(machine, goal)
    ds = dist[s]
    out = tuple(tr for tr in _graph(machine).agent[s] if goal in tr.entered or dist[tr.end] < ds)
    machine._cache[key] = out
    return out


def target_components(machine: Machine, s: int, goal: int) -> frozenset[str]:
    """PROTOCOL §4: real components with a transition from `s` that lowers `dist(., goal)`."""
    key = ("targets", goal, s)
    cached = machine._cache.get(key)
    if cached is None:
        cached = frozenset(
            tr.component for tr in progressing(machine, s, goal) if tr.action is not None
        )
        machine._cache[key] = cached
    return cached


def target_rects(machine: Machine, s: int, goal: int, view: str) -> tuple[tuple[str, Rect], ...]:
    """(component, rect) of the target components of `s` that have a bbox in `view`."""
    key = ("trects", goal, s, view)
    cached = machine._cache.get(key)
    if cached is None:
        targets = target_components(machine, s, goal)
        per_comp = machine.state_component_rects.get((s, view), {})
        cached = tuple((c, r) for c, rects in per_comp.items() if c in targets for r in rects)
        machine._cache[key] = cached
    return cached


# ------------------------------------------------------------------------------ planning


@dataclass(frozen=True, slots=True)
class PlannedStep:
    """One agent response of the optimal plan."""

    goal_index: int  # segment the step belongs to
    action: Action
    transition: CompiledTransition | None  # None for a Switch_view


class Plan:
    """The static optimal plan of an episode (PROTOCOL §4).

    Its responses (`steps`: click points, actions) are made on first use: a replay needs
    only C_opt and the optimal path, and making them was a quarter of planning a task."""

    __slots__ = ("c_opt", "transitions", "switches", "states", "_machine", "_path", "_steps")

    def __init__(
        self,
        c_opt: tuple[int, ...],  # per goal: transitions + switches of its segment
        transitions: tuple[int, ...],  # per goal
        switches: tuple[int, ...],  # per goal
        states: tuple[int, ...],  # optimal path: every state entered
        machine: Machine,
        path: tuple[tuple[int, _Option], ...],  # (goal index, the option taken) in order
    ) -> None:
        self.c_opt = c_opt
        self.transitions = transitions
        self.switches = switches
        self.states = states
        self._machine = machine
        self._path = path
        self._steps: tuple[PlannedStep, ...] | None = None

    @property
    def steps(self) -> tuple[PlannedStep, ...]:
        """The plan's responses in order: each option's view switches, then its action."""
        if self._steps is None:
            self._steps = _planned_steps(self._machine, self._path)
        return self._steps

    @property
    def length(self) -> int:
        return sum(self.c_opt)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Plan):
            return NotImplemented
        return self._key() == other._key()

    __hash__ = None  # type: ignore[assignment]

    def _key(self) -> tuple:
        return (self.c_opt, self.transitions, self.switches, self.steps, self.states)

    def __repr__(self) -> str:
        return (
            f"Plan(c_opt={self.c_opt!r}, transitions={self.transitions!r}, "
            f"switches={self.switches!r}, steps={self.steps!r}, states={self.states!r})"
        )


_Option = tuple[tuple, int, CompiledTransition, str, bool, tuple[tuple[str, str | None], ...]]
"""One way to take a tight transition from (view, unlocked), its view switches first:
(preference, switches, transition, view after, unlocked after, the switches to emit as
(view, the region's view for an active unlock or None)). The preference is PROTOCOL §4.3's
order among options of equal cost, smallest first. A plain tuple rather than an object:
planning a benchmark makes some 50,000 of them, and a tuple is made in half the time."""

_INTERACTABLE_RANK = {v: VIEW_RANK[v] for v in (*ORTHOGRAPHIC_VIEWS, DASHBOARD)}
"""The views an interaction can happen in, with their rank in the preference."""


def _region_views(machine: Machine) -> tuple[str, ...]:
    return tuple(v for v in VIEW_ORDER if v in machine.dashboard_regions)


def _state_options(graph: _Graph, s: int, view: str, unlocked: bool) -> tuple[_Option, ...]:
    """The options of every agent transition from `s` when in (view, unlocked), in order of
    preference: memoised per machine, for every goal (the planner keeps the tight ones, in
    the same order)."""
    key = (s, view, unlocked)
    got = graph.options.get(key)
    if got is None:
        found: list[_Option] = []
        for tr in graph.agent[s]:
            _add_options(found, graph.m, tr, view, unlocked)
        found.sort(key=_PREFERENCE)  # stable: options of equal preference keep file order
        got = graph.options[key] = tuple(found)
    return got


_PREFERENCE = itemgetter(0)


def _add_options(
    found: list[_Option], machine: Machine, tr: CompiledTransition, view: str, unlocked: bool
) -> None:
    """Add the ways to take `tr` from (view, unlocked) to `found`."""
    if tr.action is None:  # timed_wait needs no view, and is preferred to any view
        found.append(((tr.dangerous, 0, -1, tr.component, tr.index), 0, tr, view, unlocked, ()))
        return
    for w in tr.rects:
        rank = _INTERACTABLE_RANK.get(w)
        if rank is None:
            continue
        if w == view:
            switches, after, pre = 0, unlocked, ()
        elif w != DASHBOARD:
            switches, after, pre = 1, unlocked, ((w, None),)
        elif unlocked:
            switches, after, pre = 1, True, ((DASHBOARD, None),)
        elif view in machine.dashboard_regions:
            switches, after, pre = 1, True, ((DASHBOARD, view),)
        else:
            regions = _region_views(machine)
            if not regions:
                continue
            r = regions[0]
            switches, after, pre = 2, True, ((r, None), (DASHBOARD, r))
        preference = (tr.dangerous, switches, rank, tr.component, tr.index)
        found.append((preference, switches, tr, w, after, pre))


def _advance(goals: tuple[int, ...], i: int, tr: CompiledTransition) -> int:
    """Goal index after `tr` is taken while goal `i` is current (one goal per entered state)."""
    j = i
    for s in tr.entered:
        if j < len(goals) and s == goals[j]:
            j += 1
    return j


class _Solver:
    """Memoised minimum-switch values J(i, s, view, unlocked) over tight transitions, and
    the optimal option at each node evaluated (by the tie-breaks of PROTOCOL §4.3)."""

    def __init__(self, machine: Machine, goals: tuple[int, ...]) -> None:
        self.graph = _graph(machine)
        self.options = self.graph.options
        self.goals = goals
        self.dists = tuple([distances(machine, g) for g in goals])
        self.memo: dict[tuple, int] = {}
        self.chosen: dict[tuple, tuple[_Option, int]] = {}  # node -> (option, next goal index)

    def value(self, i: int, s: int, view: str, unlocked: bool) -> int:
        """J(i, s, view, unlocked), depth first on an explicit stack rather than Python's
        (a plan may take as many transitions as the machine has states): each node is a
        generator that yields the nodes it needs, each evaluated before it resumes, so nodes
        are evaluated exactly in the order, and with the pruning, of the plain recursion."""
        memo = self.memo
        key = (i, s, view, unlocked)
        if i >= len(self.goals):
            return 0
        got = memo.get(key)
        if got is not None:
            return got
        stack = [self._node(key)]
        while stack:
            # next()'s default, not StopIteration: a generator returning None raises none
            child = next(stack[-1], None)
            if child is None:
                stack.pop()
            else:
                stack.append(self._node(child))
        return memo[key]

    def _node(
        self, node: tuple[int, int, str, bool]
    ) -> Generator[tuple[int, int, str, bool], None, None]:
        """Evaluate one node into the memo: the best over its options, each option's rest
        taken from the memo once there, asked for by yielding its node if not (an option
        that cannot beat the best so far is skipped unasked). The options come in order of
        preference, so the first to reach the best is the optimal one: one skipped unasked
        can tie only with an earlier one that reached the best already."""
        goals, memo = self.goals, self.memo
        i, s, view, unlocked = node
        n = len(goals)
        goal = goals[i]
        best = INF
        if s == goal:  # goals complete when entered (PROTOCOL §3.4)
            memo[node] = best
            return
        dist = self.dists[i]
        ds = dist[s]
        chosen: tuple[_Option, int] | None = None
        options = self.options.get((s, view, unlocked))  # `_state_options`, looked up inline
        if options is None:
            options = _state_options(self.graph, s, view, unlocked)
        for opt in options:
            _, switches, tr, to_view, to_unlocked, _ = opt
            if switches >= best:
                continue
            # a tight transition, as `progressing` has it (inline: the planner's hot loop)
            if goal in tr.entered:
                j = _advance(goals, i, tr)
            elif dist[tr.end] < ds:
                j = i
            else:
                continue
            child = (j, tr.end, to_view, to_unlocked)
            rest = 0 if j >= n else memo.get(child)
            if rest is None:
                yield child
                rest = memo[child]
            if switches + rest < best:
                best = switches + rest
                chosen = (opt, j)
        memo[node] = best
        if chosen is not None:
            self.chosen[node] = chosen


def _click_point(machine: Machine, tr: CompiledTransition, view: str) -> tuple[float, float]:
    """A point that triggers `tr` in `view` (memoised per machine: it does not depend on the
    task)."""
    key = ("click", tr.source, tr.component, tr.index, view)
    got = machine._cache.get(key)
    if got is None:
        got = machine._cache[key] = _find_click_point(machine, tr, view)
    return got


def _find_click_point(machine: Machine, tr: CompiledTransition, view: str) -> tuple[float, float]:
    """The centre of the smallest rect of `tr` in `view`, or the first grid point inside it
    that hits no smaller rival whose action and params also match."""
    rects = sorted(tr.rects[view], key=lambda r: r[4])
    rivals = [
        (other, rs)
        for other, rs in machine.by_state_view.get((tr.source, view), ())
        if other is not tr and other.action == tr.action
    ]
    params = _concrete_params(tr)

    def wins(px: float, py: float) -> bool:
        mine = min(r[4] for r in tr.rects[view] if rect_contains(r, px, py))
        for other, rs in rivals:
            if not other.params_match(params):
                continue
            areas = [r[4] for r in rs if rect_contains(r, px, py)]
            if areas and (min(areas), other.component, other.index) < (
                mine,
                tr.component,
                tr.index,
            ):
                return False
        return True

    for r in rects:
        for fx in (0.5, 0.3, 0.7, 0.1, 0.9):
            for fy in (0.5, 0.3, 0.7, 0.1, 0.9):
                px = round(r[0] + (r[2] - r[0]) * fx)
                py = round(r[1] + (r[3] - r[1]) * fy)
                if rect_contains(r, px, py) and wins(px, py):
                    return (float(px), float(py))
    r = rects[0]
    return ((r[0] + r[2]) / 2.0, (r[1] + r[3]) / 2.0)


def _concrete_params(tr: CompiledTransition) -> tuple[str, ...]:
    if not tr.params:
        return ()
    return tuple("0" if p == "*" else p for p in tr.params)


def _region_point(machine: Machine, view: str) -> tuple[float, float]:
    r = machine.dashboard_regions[view][0]
    return (float(round((r[0] + r[2]) / 2.0)), float(round((r[1] + r[3]) / 2.0)))


def plan_goals(
    machine: Machine,
    start: int,
    view: str,
    unlocked: bool,
    goals: tuple[int, ...],
    *,
    where: str = "",
) -> Plan:
    """The optimal plan for `goals` from (start, view, unlocked); raises TaskError if none."""
    solver = _solver(machine, goals)
    _check_goals(machine, start, goals, solver.dists, where)
    n = len(goals)
    if solver.value(0, start, view, unlocked) >= INF:
        raise TaskError(f"{where}the goals need a component that no interactable view shows")
    chosen = solver.chosen  # every node of the optimal path was evaluated, its choice kept
    c_trans = [0] * n
    c_switch = [0] * n
    path: list[tuple[int, _Option]] = []
    states: list[int] = []
    i, s, v, u = 0, start, view, unlocked
    while i < n:
        opt, j = chosen[i, s, v, u]
        _, _, tr, v, u, pre = opt
        path.append((i, opt))
        c_switch[i] += len(pre)  # a Switch_view each
        c_trans[i] += 1
        states += tr.entered
        i, s = j, tr.end
    c_opt = tuple(map(add, c_trans, c_switch))
    return Plan(c_opt, tuple(c_trans), tuple(c_switch), tuple(states), machine, tuple(path))


def _planned_steps(
    machine: Machine, path: tuple[tuple[int, _Option], ...]
) -> tuple[PlannedStep, ...]:
    """The responses of a plan's options: each one's view switches, then its action."""
    steps: list[PlannedStep] = []
    for i, (_, _, tr, view, _, pre) in path:
        for target_view, via in pre:
            coord = _region_point(machine, via) if via is not None else None
            steps.append(PlannedStep(i, Action(SWITCH_VIEW, coord, (target_view,)), None))
        if tr.action is None:
            act = Action(TIMED_WAIT, None, ())
        else:
            act = Action(tr.action, _click_point(machine, tr, view), _concrete_params(tr))
        steps.append(PlannedStep(i, act, tr))
    return tuple(steps)


def _check_goals(
    machine: Machine,
    start: int,
    goals: tuple[int, ...],
    dists: tuple[tuple[int, ...], ...],
    where: str,
) -> None:
    """Static checks with a message naming the goal: reachability (`dists`: each goal's
    distances), and no goal equal to the state in which it becomes current (which is fixed:
    the chain end of the previous goal)."""
    s = start
    i = 0
    n = len(goals)
    while i < n:
        g = goals[i]
        if s == g:
            raise TaskError(
                f"{where}goal {i + 1} {machine.states[g]!r} is the state in which it becomes "
                "current; goals complete when entered"
            )
        if dists[i][s] >= INF:
            raise TaskError(
                f"{where}goal {i + 1} {machine.states[g]!r} is unreachable from {machine.states[s]!r}"
            )
        i += 1
        for x in machine.immediate_chain[g]:
            if i < n and x == goals[i]:
                i += 1
        s = machine.chain_end[g]


def _solver(machine: Machine, goals: tuple[int, ...]) -> _Solver:
    """The solver of a goal sequence, memoised per machine (tasks of a device share them)."""
    key = ("solver", goals)
    solver = machine._cache.get(key)
    if solver is None:
        solver = _Solver(machine, goals)
        machine._cache[key] = solver
    return solver


def next_optimal_step(
    machine: Machine, state: int, view: str, unlocked: bool, goals: tuple[int, ...]
) -> PlannedStep | None:
    """The first response of an optimal plan for `goals` from this situation (PROTOCOL §4.5):
    what the planner would do next. None when the goals cannot be planned from here."""
    if not goals:
        return None
    try:
        plan = plan_goals(machine, state, view, unlocked, goals)
    except TaskError:
        return None
    return plan.steps[0] if plan.steps else None


def c_opt_dynamic(machine: Machine, state: int, view: str, unlocked: bool, goal: int) -> int | None:
    """C_opt of `goal` alone from the actual situation (PROTOCOL §4, for PSR); None if unreachable."""
    d = distances(machine, goal)[state]
    if state == goal:
        return 0
    if d >= INF:
        return None
    w = _solver(machine, (goal,)).value(0, state, view, unlocked)
    return None if w >= INF else d + w
