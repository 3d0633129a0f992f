"""Validate a state machine record and compile it into lookup tables for the simulator.

Compilation happens once per device: bboxes are converted to the agent's 0..1000 scale and
grouped per (state, view), immediate chains are resolved, error states marked. The
simulator, planner and classifier only read these tables.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from .._errors import Problem, SSMError
from ._records import StateMachine
from ._vocab import (
    ATOMIC_ACTIONS,
    DASHBOARD,
    IMMEDIATE,
    ORTHOGRAPHIC_VIEWS,
    PSEUDO_COMPONENTS,
    SCALE,
    STANDARD_VIEWS,
    TIMED_WAIT,
    VIEW_RANK,
    normalize_param,
)

_SCALE = float(SCALE)

Rect = tuple[float, float, float, float, float]
"""(x0, y0, x1, y1, area) on the agent's 0..1000 scale."""


def rect_from_coordinate(coord: list[float]) -> Rect:
    """`[x, y, w, h, W, H]` in pixels -> normalised rect (PROTOCOL §1.2)."""
    x, y, w, h, width, height = coord
    x0 = x * _SCALE / width
    y0 = y * _SCALE / height
    wn = w * _SCALE / width
    hn = h * _SCALE / height
    return (x0, y0, x0 + wn, y0 + hn, wn * hn)


def rect_contains(rect: Rect, px: float, py: float) -> bool:
    """Closed-interval containment, as PROTOCOL §1.2 defines it."""
    return rect[0] <= px <= rect[2] and rect[1] <= py <= rect[3]


def rect_distance(rect: Rect, px: float, py: float) -> float:
    """Euclidean distance from a point to a rect (0 inside)."""
    dx = max(rect[0] - px, 0.0, px - rect[2])
    dy = max(rect[1] - py, 0.0, py - rect[3])
    if dx == 0.0:
        return dy
    if dy == 0.0:
        return dx
    return (dx * dx + dy * dy) ** 0.5


@dataclass(frozen=True, slots=True)
class CompiledTransition:
    """One transition with everything precomputed."""

    component: str
    index: int  # position in the component's list (tie-break "list order")
    source: int
    target: int
    action: str | None  # lowercase atomic action; None for immediate/timed_wait
    params: tuple[str, ...] | None  # None = matches any params
    description: str
    rects: dict[str, tuple[Rect, ...]]  # view -> rects
    entered: tuple[int, ...]  # target, then the immediate chain after it
    end: int  # the stable state after the chain
    dangerous: bool  # the chain enters an error state

    def params_match(self, params: tuple[str, ...]) -> bool:
        """PROTOCOL §1.2: '*' in the transition matches anything; empty/missing matches any."""
        required = self.params
        if not required:
            return True
        if len(required) != len(params):
            return False
        for want, got in zip(required, params, strict=True):
            if want != "*" and want != got:
                return False
        return True


@dataclass(slots=True)
class Machine:
    """A compiled SSM: immutable after construction."""

    device_id: str
    category: str
    name: str
    source: str
    states: tuple[str, ...]
    state_index: dict[str, int]
    descriptions: tuple[str, ...]
    initial: int
    error_states: frozenset[int]
    views: tuple[str, ...]
    immediate_chain: tuple[tuple[int, ...], ...]  # per state: states entered after it
    chain_end: tuple[int, ...]  # per state: stable state after its immediate chain
    transitions: tuple[CompiledTransition, ...]
    by_state: tuple[tuple[CompiledTransition, ...], ...]  # agent transitions per state
    wait: tuple[CompiledTransition | None, ...]  # timed_wait transition per state
    by_state_view: dict[tuple[int, str], tuple[tuple[CompiledTransition, tuple[Rect, ...]], ...]]
    component_rects: dict[str, tuple[tuple[str, Rect], ...]]  # view -> (component, rect)
    state_component_rects: dict[tuple[int, str], dict[str, tuple[Rect, ...]]]
    dashboard_regions: dict[str, tuple[Rect, ...]]
    images: dict[str, tuple[str, int, int]]
    ssm: StateMachine = field(repr=False)
    _cache: dict = field(default_factory=dict, repr=False)

    @property
    def has_dashboard(self) -> bool:
        return bool(self.dashboard_regions)

    def state_id(self, name: str) -> int:
        return self.state_index[name]

    def in_dashboard_region(self, view: str, px: float, py: float) -> bool:
        return any(rect_contains(r, px, py) for r in self.dashboard_regions.get(view, ()))


def _is_error_state(name: str, state) -> bool:
    return name == "Error" or bool(state.is_error)


def validate_machine(
    ssm: StateMachine, path: str, *, require_geometry: bool = True
) -> list[Problem]:
    """Every problem of PROTOCOL §1.2 (and a few more), each naming file, state and component.

    `require_geometry=False` validates a category template (UCSM): no bboxes needed.
    Returns problems of severity "error" and "warning"; errors make the SSM unusable.
    """
    problems: list[Problem] = []

    def err(where: str, message: str, severity: str = "error") -> None:
        problems.append(Problem(path, where, message, severity))

    if not ssm.states:
        err("states", "the machine has no states")
        return problems
    if ssm.initial_state not in ssm.states:
        err("initial_state", f"unknown initial_state {ssm.initial_state!r}")
    offered = _check_views(ssm, err)
    for sname, state in ssm.states.items():
        for comp, transitions in state.on.items():
            _check_component(ssm, sname, comp, transitions, offered, require_geometry, err)
    _check_chains(ssm, err)
    return problems


_Report = Callable[..., None]
"""`err(where, message, severity="error")`: records one problem."""


def _check_views(ssm: StateMachine, err: _Report) -> set[str]:
    """The views the machine declares and its dashboard regions; returns the views offered."""
    views = list(ssm.views) if ssm.views is not None else list(STANDARD_VIEWS)
    for v in views:
        if v.lower() not in STANDARD_VIEWS and v.lower() != DASHBOARD:
            err("views", f"unknown view {v!r} in views")
    offered = {v.lower() for v in views}
    regions = ssm.dashboard.regions if ssm.dashboard is not None else []
    if regions:
        offered.add(DASHBOARD)
    for i, region in enumerate(regions):
        where = f"dashboard.regions[{i}]"
        view = region.view.lower()
        if view not in ORTHOGRAPHIC_VIEWS:
            err(
                where, f"dashboard region on {region.view!r}: regions must be on orthographic views"
            )
        elif view not in offered:
            err(where, f"dashboard region on view {region.view!r} that the device does not offer")
        for message in _coordinate_problems(region.coordinate):
            err(where, message)
    return offered


def _check_component(
    ssm: StateMachine,
    sname: str,
    comp: str,
    transitions: list,
    offered: set[str],
    require_geometry: bool,
    err: _Report,
) -> None:
    """The transitions of one component in one state: targets, actions, boxes, and two
    with the same trigger (only the first can fire). Where a problem is, is written out only
    for a problem (a benchmark has some 20,000 transitions and boxes)."""

    def at(k: int | None = None, b: int | None = None) -> str:
        where = f"state {sname!r}, component {comp!r}"
        if k is not None:
            where += f", transition {k}"
        return where if b is None else f"{where}, bbox {b}"

    if not transitions:
        err(at(), "empty transition list", "warning")
    pseudo = comp in PSEUDO_COMPONENTS
    if pseudo and len(transitions) > 1:
        err(at(), f"more than one {comp} transition; only the first is taken", "warning")
    states = ssm.states
    seen_triggers: dict[tuple, int] = {}
    for k, tr in enumerate(transitions):
        if tr.next_state not in states:
            err(at(k), f"dangling next_state {tr.next_state!r}")
        if pseudo:
            if tr.bbox:
                err(at(k), f"{comp} transitions have no bbox; it is ignored", "warning")
            continue
        action = tr.atomic_action.lower() if tr.atomic_action else None
        if action is None:
            if require_geometry:
                err(at(k), "missing atomic_action")
        elif action not in ATOMIC_ACTIONS:
            err(at(k), f"unknown atomic action {tr.atomic_action!r}")
        if require_geometry and not tr.bbox:
            err(at(k), "no bbox: the component cannot be clicked in any view", "warning")
        for b, box in enumerate(tr.bbox):
            if box.view.lower() not in offered:
                err(at(k, b), f"bbox on unknown view {box.view!r}")
            for message in _coordinate_problems(box.coordinate):
                err(at(k, b), message)
        if action is not None:
            params = tr.parameter
            trigger = (action, tuple(map(normalize_param, params)) if params else ())
            first = seen_triggers.setdefault(trigger, k)
            if first != k:
                err(
                    at(k),
                    f"same action and params as transition {first}; only the first can ever fire",
                    "warning",
                )


def _check_chains(ssm: StateMachine, err: _Report) -> None:
    """Cycles made only of immediate transitions (the simulator would never stop), and
    chains too long to compile (PROTOCOL §1.5)."""
    successor = _immediate_successors(ssm)
    cycles = _immediate_cycles(ssm, successor)
    for cycle in cycles:
        err(
            f"state {cycle[0]!r}, component 'immediate'",
            f"cycle of immediate transitions: {' -> '.join([*cycle, cycle[0]])}",
        )
    if not cycles:
        held = _chain_states_held(ssm, successor)
        if held > MAX_CHAIN_STATES:
            err(
                "component 'immediate'",
                f"immediate chains too long: compiling would hold {held:,} entered states "
                f"(at most {MAX_CHAIN_STATES:,}, PROTOCOL §1.5)",
            )


MAX_CHAIN_STATES = 1 << 24
"""The states entered through `immediate` chains that a compiled machine holds, summed over
its states and transitions (each keeps the chain after it): the bound on its memory."""


def _immediate_successors(ssm: StateMachine) -> dict[str, str | None]:
    """Per state, the state its first `immediate` transition leads to (None: none, or a
    state the machine does not have)."""
    states = ssm.states
    successor: dict[str, str | None] = {}
    for name, sdef in states.items():
        imm = sdef.on.get(IMMEDIATE)
        nxt = imm[0].next_state if imm else None
        successor[name] = nxt if nxt in states else None
    return successor


def _chain_states_held(ssm: StateMachine, successor: dict[str, str | None]) -> int:
    """What compiling holds of the immediate chains (see `MAX_CHAIN_STATES`): every state's
    chain, and for every other transition its target and the target's chain. Linear time;
    the machine has no immediate cycle."""
    length: dict[str, int] = {}
    for start in successor:
        path: list[str] = []
        current = start
        while current not in length:
            nxt = successor[current]
            if nxt is None:
                length[current] = 0
                break
            path.append(current)
            current = nxt
        for name in reversed(path):
            length[name] = 1 + length[successor[name]]
    held = sum(length.values())
    for sdef in ssm.states.values():
        for comp, trs in sdef.on.items():
            if comp != IMMEDIATE:
                held += len(trs)
                for tr in trs:
                    held += length.get(tr.next_state, 0)
    return held


def _immediate_cycles(ssm: StateMachine, successor: dict[str, str | None]) -> list[list[str]]:
    """Every cycle of immediate transitions, listed from its first member in file order, in
    the order of those members (each cycle reported once).

    A state has at most one immediate successor (its first `immediate` transition), so one
    walk from each state not yet seen, marking the states of the walk, finds every cycle in
    time linear in the states (a long chain is walked once, not once per state in it)."""
    seen: set[str] = set()
    cycles: list[list[str]] = []
    for start in successor:
        walk: dict[str, int] = {}  # state -> its position in this walk
        current: str | None = start
        while current is not None and current not in seen:
            seen.add(current)
            walk[current] = len(walk)
            current = successor[current]
        if current is not None and current in walk:  # the walk closed on itself
            cycles.append(list(walk)[walk[current] :])
    if cycles:
        order = {name: i for i, name in enumerate(ssm.states)}
        for c, members in enumerate(cycles):
            first = min(range(len(members)), key=lambda k: order[members[k]])
            cycles[c] = members[first:] + members[:first]
        cycles.sort(key=lambda cycle: order[cycle[0]])
    return cycles


MAX_PIXELS = 1 << 24
"""The largest number a box or a dashboard region may hold, in pixels (PROTOCOL §1.5): a
picture is far smaller, and the planner's arithmetic on the 0..1000 scale stays finite."""


def _coordinate_problems(coord: list[float]) -> list[str]:
    """What is wrong with a box's [x, y, w, h, W, H] (nothing, mostly: the numbers are
    formatted only for a message, and a benchmark has some 20,000 boxes)."""
    if len(coord) != 6:
        return [f"coordinate must be [x, y, w, h, W, H], got {len(coord)} numbers"]
    x, y, w, h, width, height = coord
    m = MAX_PIXELS  # -m <= v <= m holds for no NaN and no infinity
    if x >= 0 and y >= 0 and w > 0 and h > 0 and x + w <= width <= m and y + h <= height <= m:
        return []  # the usual box, tested at once: this implies every test below passes
    if not (
        -m <= x <= m
        and -m <= y <= m
        and -m <= w <= m
        and -m <= h <= m
        and -m <= width <= m
        and -m <= height <= m
    ):
        # normalising multiplies by the scale: a larger number overflows to inf, then NaN
        numbers = ", ".join(f"{v:g}" for v in coord)
        return [f"coordinate [{numbers}] holds a number past {MAX_PIXELS:,} pixels"]
    if width <= 0 or height <= 0:
        return [f"image size W x H must be positive, got {width:g} x {height:g}"]
    problems = []
    if w <= 0 or h <= 0:
        problems.append(f"bbox with non-positive size w={w:g}, h={h:g}")
    if x < 0 or y < 0 or x + w > width or y + h > height:
        problems.append(
            f"bbox [{x:g}, {y:g}, {w:g}, {h:g}] outside its {width:g} x {height:g} image"
        )
    return problems


def compile_machine(
    ssm: StateMachine, *, device_id: str | None = None, source: str = "<memory>"
) -> Machine:
    """Validate and compile; raises `SSMError` listing every error (warnings are kept)."""
    problems = validate_machine(ssm, source)
    errors = [p for p in problems if p.severity == "error"]
    if errors:
        raise SSMError(errors)

    names = tuple(ssm.states)
    index = {n: i for i, n in enumerate(names)}
    error_states = frozenset(
        i for i, (nm, sdef) in enumerate(ssm.states.items()) if _is_error_state(nm, sdef)
    )
    chains, ends = _immediate_chains(ssm, names, index)
    views, regions = _offered_views(ssm)
    transitions, by_state, wait = _compile_transitions(ssm, index, chains, ends, error_states)
    by_state_view, component_rects, state_component_rects = _rect_tables(transitions)
    images = {}
    if ssm.images:
        for view, ref in ssm.images.items():
            images[view.lower()] = (ref.path, ref.width, ref.height)

    return Machine(
        device_id=device_id or ssm.device_id or ssm.name,
        category=ssm.category or ssm.name,
        name=ssm.name,
        source=source,
        states=names,
        state_index=index,
        descriptions=tuple([sdef.description for sdef in ssm.states.values()]),
        initial=index[ssm.initial_state],
        error_states=error_states,
        views=views,
        immediate_chain=tuple(chains),
        chain_end=tuple(ends),
        transitions=tuple(transitions),
        by_state=tuple(map(tuple, by_state)),
        wait=tuple(wait),
        by_state_view={k: tuple(v) for k, v in by_state_view.items()},
        # sorted by (component, rect)
        component_rects={v: tuple(sorted(d)) for v, d in component_rects.items()},
        state_component_rects={
            k: {c: tuple(rs) for c, rs in sorted(d.items())}
            for k, d in state_component_rects.items()
        },
        dashboard_regions={v: tuple(r) for v, r in regions.items()},
        images=images,
        ssm=ssm,
    )


def _immediate_chains(
    ssm: StateMachine, names: tuple[str, ...], index: dict[str, int]
) -> tuple[list[tuple[int, ...]], list[int]]:
    """Per state, the states its `immediate` chain enters after it, and the stable state at
    its end (PROTOCOL §3.4). A state's chain is its successor's with the successor in front:
    built back from each stable end, every state once (a long chain is not walked again for
    each state in it)."""
    n = len(names)
    immediate_next: list[int | None] = [None] * n
    for i, nm in enumerate(names):
        imm = ssm.states[nm].on.get(IMMEDIATE)
        if imm:
            immediate_next[i] = index[imm[0].next_state]
    chains: list[tuple[int, ...]] = [()] * n
    built = [False] * n
    for i in range(n):
        path: list[tuple[int, int]] = []  # (state, its successor) up to a built state
        cur = i
        while not built[cur] and (nxt := immediate_next[cur]) is not None:
            path.append((cur, nxt))
            cur = nxt
        built[cur] = True
        for state, succ in reversed(path):
            chains[state] = (succ, *chains[succ])
            built[state] = True
    ends = [chain[-1] if chain else i for i, chain in enumerate(chains)]
    return chains, ends


def _offered_views(ssm: StateMachine) -> tuple[tuple[str, ...], dict[str, list[Rect]]]:
    """The views the device offers, in the order of `VIEW_RANK` (the dashboard among them
    when it has a region), and its dashboard regions by view."""
    views = list(ssm.views) if ssm.views is not None else list(STANDARD_VIEWS)
    view_list = [v.lower() for v in views]
    regions: dict[str, list[Rect]] = {}
    if ssm.dashboard is not None:
        for region in ssm.dashboard.regions:
            regions.setdefault(region.view.lower(), []).append(
                rect_from_coordinate(region.coordinate)
            )
    if regions and DASHBOARD not in view_list:
        view_list.append(DASHBOARD)
    view_list.sort(key=lambda v: VIEW_RANK.get(v, len(VIEW_RANK)))
    return tuple(view_list), regions


def _compile_transitions(
    ssm: StateMachine,
    index: dict[str, int],
    chains: list[tuple[int, ...]],
    ends: list[int],
    error_states: frozenset[int],
) -> tuple[
    list[CompiledTransition], list[list[CompiledTransition]], list[CompiledTransition | None]
]:
    """Every transition but the `immediate` ones, compiled in file order; the agent's
    transitions of each state, and each state's `timed_wait` transition (the first)."""
    n = len(index)
    transitions: list[CompiledTransition] = []
    by_state: list[list[CompiledTransition]] = [[] for _ in range(n)]
    wait: list[CompiledTransition | None] = [None] * n
    for i, sdef in enumerate(ssm.states.values()):  # the order of `index`
        for comp, trs in sdef.on.items():
            if comp == IMMEDIATE:
                continue
            timed = comp == TIMED_WAIT
            for k, tr in enumerate(trs):
                dst = index[tr.next_state]
                entered = (dst, *chains[dst])
                # arguments by position, in field order: a benchmark compiles some 15,000
                ct = CompiledTransition(
                    comp,  # component
                    k,  # index
                    i,  # source
                    dst,  # target
                    None if timed else (tr.atomic_action or "").lower() or None,  # action
                    tuple(map(normalize_param, tr.parameter)) if tr.parameter else None,  # params
                    tr.transition_description,  # description
                    {} if timed else _view_rects(tr.bbox),  # rects
                    entered,  # entered
                    ends[dst],  # end
                    not error_states.isdisjoint(entered),  # dangerous
                )
                transitions.append(ct)
                if not timed:
                    by_state[i].append(ct)
                elif wait[i] is None:
                    wait[i] = ct
    return transitions, by_state, wait


def _view_rects(boxes: list) -> dict[str, tuple[Rect, ...]]:
    """A transition's boxes as rects by view, in file order."""
    rects: dict[str, tuple[Rect, ...]] = {}
    for box in boxes:
        view = box.view.lower()
        rects[view] = (*rects.get(view, ()), rect_from_coordinate(box.coordinate))
    return rects


def _rect_tables(transitions: list[CompiledTransition]) -> tuple[dict, dict, dict]:
    """The agent transitions' boxes looked up three ways: (state, view) -> [(transition,
    its rects)], view -> {(component, rect)}, (state, view) -> {component: [rects]}."""
    by_state_view: dict[tuple[int, str], list] = {}
    state_component_rects: dict[tuple[int, str], dict[str, list[Rect]]] = {}
    component_rects: dict[str, dict[tuple[str, Rect], None]] = {}
    for ct in transitions:
        if ct.action is None:
            continue
        source, comp = ct.source, ct.component
        for view, rects in ct.rects.items():
            key = (source, view)
            listed = by_state_view.get(key)
            if listed is None:
                listed = by_state_view[key] = []
                state_component_rects[key] = {}
            listed.append((ct, rects))
            per_comp = state_component_rects[key]
            bucket = per_comp.get(comp)
            if bucket is None:
                bucket = per_comp[comp] = []
            in_view = component_rects.get(view)
            if in_view is None:
                in_view = component_rects[view] = {}
            for r in rects:
                if r not in bucket:
                    bucket.append(r)
                in_view[(comp, r)] = None
    return by_state_view, component_rects, state_component_rects
