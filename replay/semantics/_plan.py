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
    n = len(machine.states)
    dist = [INF] * n
    dist[goal] = 0
    reverse: dict[int, list[int]] = {}
    layer: list[int] = []
    for s in range(n):
        if machine.immediate_chain[s]:
            continue  # the agent never stands in a transient state
        for tr in _agent_transitions(machine, s):
            if goal in tr.entered:
                if dist[s] > 1:
                    dist[s] = 1
                    layer.append(s)
            else:
                reverse.setdefault(tr.end, []).append(s)
    frontier = layer
    while frontier:
        nxt: list[int] = []
        for s in frontier:
            d = dist[s] + 1
            for p in reverse.get(s, ()):
                if dist[p] == INF:
                    dist[p] = d
                    nxt.append(p)
        frontier = nxt
    for s in range(n):
        chain = machine.immediate_chain[s]
        if chain and s != goal:
            dist[s] = 0 if goal in chain else dist[machine.chain_end[s]]
    result = tuple(dist)
    machine._cache[key] = result
    return result


def _agent_transitions(machine: Machine, s: int) -> tuple[CompiledTransition, ...]:
    wait = machine.wait[s]
    return machine.by_state[s] + ((wait,) if wait is not None else ())


def progressing(machine: Machine, s: int, goal: int) -> tuple[CompiledTransition, ...]:
    """Transitions from `s` that complete `goal` or lower its distance (timed_wait included)."""
    key = ("prog", goal, s)
    cached = machine._cache.get(key)
    if cached is not None:
        return cached
    dist = distances(machine, goal)
    ds = dist[s]
    out = tuple(
        tr for tr in _agent_transitions(machine, s) if goal in tr.entered or dist[tr.end] < ds
    )
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


class _Option:
    """One way to take a tight transition from (view, unlocked): switches first, then act."""

    __slots__ = ("tr", "switches", "view", "unlocked", "pre")

    def __init__(self, tr, switches, view, unlocked, pre):
        self.tr = tr
        self.switches = switches
        self.view = view
        self.unlocked = unlocked
        self.pre = pre  # tuple of (view, via_region_view or None) switches to emit


def _region_views(machine: Machine) -> tuple[str, ...]:
    return tuple(v for v in VIEW_ORDER if v in machine.dashboard_regions)


def _options(
    machine: Machine, tr: CompiledTransition, view: str, unlocked: bool
) -> tuple[_Option, ...]:
    """The ways to take `tr` from (view, unlocked), memoised per machine."""
    key = ("options", tr.source, tr.component, tr.index, view, unlocked)
    got = machine._cache.get(key)
    if got is None:
        got = machine._cache[key] = tuple(_find_options(machine, tr, view, unlocked))
    return got


def _find_options(
    machine: Machine, tr: CompiledTransition, view: str, unlocked: bool
) -> list[_Option]:
    if tr.action is None:  # timed_wait needs no view
        return [_Option(tr, 0, view, unlocked, ())]
    opts: list[_Option] = []
    for w in tr.rects:
        if w not in ORTHOGRAPHIC_VIEWS and w != DASHBOARD:
            continue
        if w == view:
            opts.append(_Option(tr, 0, w, unlocked, ()))
        elif w != DASHBOARD:
            opts.append(_Option(tr, 1, w, unlocked, ((w, None),)))
        elif unlocked:
            opts.append(_Option(tr, 1, w, True, ((DASHBOARD, None),)))
        elif view in machine.dashboard_regions:
            opts.append(_Option(tr, 1, w, True, ((DASHBOARD, view),)))
        else:
            regions = _region_views(machine)
            if regions:
                r = regions[0]
                opts.append(_Option(tr, 2, w, True, ((r, None), (DASHBOARD, r))))
    return opts


def _advance(goals: tuple[int, ...], i: int, tr: CompiledTransition) -> int:
    """Goal index after `tr` is taken while goal `i` is current (one goal per entered state)."""
    j = i
    for s in tr.entered:
        if j < len(goals) and s == goals[j]:
            j += 1
    return j


class _Solver:
    """Memoised minimum-switch values J(i, s, view, unlocked) over tight transitions."""

    def __init__(self, machine: Machine, goals: tuple[int, ...]) -> None:
        self.m = machine
        self.goals = goals
        self.memo: dict[tuple, int] = {}

    def value(self, i: int, s: int, view: str, unlocked: bool) -> int:
        """J(i, s, view, unlocked), depth first on an explicit stack rather than Python's
        (a plan may take as many transitions as the machine has states): each node is a
        generator that yields the nodes it needs and is sent their values, so nodes are
        evaluated exactly in the order, and with the pruning, of the plain recursion."""
        memo = self.memo
        key = (i, s, view, unlocked)
        if i >= len(self.goals):
            return 0
        got = memo.get(key)
        if got is not None:
            return got
        stack = [(key, self._node(*key))]
        sent: int | None = None
        while stack:
            node, frame = stack[-1]
            try:
                child = frame.send(sent)
            except StopIteration as done:
                memo[node] = sent = done.value
                stack.pop()
                continue
            sent = None
            stack.append((child, self._node(*child)))
        return memo[key]

    def _node(
        self, i: int, s: int, view: str, unlocked: bool
    ) -> Generator[tuple[int, int, str, bool], int, int]:
        """The value of one node: the best over its options, each option's rest taken from
        the memo or asked for by yielding its node (an option that cannot beat the best so
        far is skipped unasked)."""
        goals, memo, m = self.goals, self.memo, self.m
        n = len(goals)
        best = INF
        goal = goals[i]
        if s == goal:  # goals complete when entered (PROTOCOL §3.4)
            return best
        for tr in progressing(m, s, goal):
            j = _advance(goals, i, tr)
            end = tr.end
            for opt in _options(m, tr, view, unlocked):
                switches = opt.switches
                if switches >= best:
                    continue
                child = (j, end, opt.view, opt.unlocked)
                rest = 0 if j >= n else memo.get(child)
                if rest is None:
                    rest = yield child
                if switches + rest < best:
                    best = switches + rest
        return best

    def choose(self, i: int, s: int, view: str, unlocked: bool) -> tuple[_Option, int]:
        """The optimal option at a node, by the tie-breaks of PROTOCOL §4.3."""
        target = self.value(i, s, view, unlocked)
        goals, memo, m = self.goals, self.memo, self.m
        n = len(goals)
        best: tuple | None = None
        chosen: tuple[_Option, int] | None = None
        for tr in progressing(m, s, goals[i]):
            j = _advance(goals, i, tr)
            end = tr.end
            for opt in _options(m, tr, view, unlocked):
                rest = 0 if j >= n else memo.get((j, end, opt.view, opt.unlocked))
                if rest is None:  # a node the value's pruning never asked for
                    rest = self.value(j, end, opt.view, opt.unlocked)
                if opt.switches + rest != target:
                    continue
                rank = -1 if tr.action is None else VIEW_RANK.get(opt.view, len(VIEW_RANK))
                key = (tr.dangerous, opt.switches, rank, tr.component, tr.index)
                if best is None or key < best:
                    best, chosen = key, (opt, j)
        assert chosen is not None
        return chosen


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
    _check_goals(machine, start, goals, where)
    solver = _solver(machine, goals)
    n = len(goals)
    if solver.value(0, start, view, unlocked) >= INF:
        raise TaskError(f"{where}the goals need a component that no interactable view shows")
    c_trans = [0] * n
    c_switch = [0] * n
    path: list[tuple[int, _Option]] = []
    states: list[int] = []
    i, s, v, u = 0, start, view, unlocked
    while i < n:
        opt, j = solver.choose(i, s, v, u)
        tr = opt.tr
        path.append((i, opt))
        c_switch[i] += len(opt.pre)  # a Switch_view each
        c_trans[i] += 1
        states.extend(tr.entered)
        i, s, v, u = j, tr.end, opt.view, opt.unlocked
    c_opt = tuple(t + w for t, w in zip(c_trans, c_switch, strict=True))
    return Plan(c_opt, tuple(c_trans), tuple(c_switch), tuple(states), machine, tuple(path))


def _planned_steps(
    machine: Machine, path: tuple[tuple[int, _Option], ...]
) -> tuple[PlannedStep, ...]:
    """The responses of a plan's options: each one's view switches, then its action."""
    steps: list[PlannedStep] = []
    for i, opt in path:
        tr = opt.tr
        for target_view, via in opt.pre:
            coord = _region_point(machine, via) if via is not None else None
            steps.append(PlannedStep(i, Action(SWITCH_VIEW, coord, (target_view,)), None))
        if tr.action is None:
            act = Action(TIMED_WAIT, None, ())
        else:
            act = Action(tr.action, _click_point(machine, tr, opt.view), _concrete_params(tr))
        steps.append(PlannedStep(i, act, tr))
    return tuple(steps)


def _check_goals(machine: Machine, start: int, goals: tuple[int, ...], where: str) -> None:
    """Static checks with a message naming the goal: reachability, and no goal equal to the
    state in which it becomes current (which is fixed: the chain end of the previous goal)."""
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
        if distances(machine, g)[s] >= INF:
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
