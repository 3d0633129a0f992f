"""Lookup tables of the columnar replay (`_columnar.py`), kept per process.

The columnar path classifies a whole batch of steps with array operations, so everything a
step is classified against has an integer id and lives in flat numpy columns:

- actions: every distinct parsed action `(type, params)` or parse failure -> an action id;
- outcomes: every distinct simulator outcome met so far -> an outcome id (kind, detail,
  text, transition, entered states...);
- geometry: per machine and view the component rects; per (machine, goal) the distances and,
  filled lazily, the target rects per (state, view) and the switch-class view mask per state.

Tables only grow (bounded by the benchmark: machines, goals, distinct actions); `reset`
drops everything when the action vocabulary gets unusually large.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pyarrow as pa

from ..semantics._episode import EpisodeSetup
from ..semantics._machine import Machine
from ..semantics._parse import Action, ParsedAction
from ..semantics._plan import c_opt_dynamic, distances, target_components, target_rects
from ..semantics._step import Outcome
from ..semantics._vocab import (
    ACTION_NAMES,
    DASHBOARD,
    FEEDBACK_KINDS,
    INTERACTIONS,
    ORTHOGRAPHIC_VIEWS,
    SWITCH_VIEW,
    VIEW_ORDER,
)
from ._columnar_arrow import Vocab

VIEW_CODES = {v: i for i, v in enumerate(VIEW_ORDER)}
"""Every view a machine can offer (validated at load) -> a small integer."""
N_VIEWS = len(VIEW_ORDER)
INTERACTABLE = np.array([v in ORTHOGRAPHIC_VIEWS or v == DASHBOARD for v in VIEW_ORDER])
TYPE_CODES = {name: i for i, name in enumerate(ACTION_NAMES)}
"""Action type -> code: interactions 0..4, then switch_view, timed_wait; -1 = no action."""
T_SWITCH = TYPE_CODES[SWITCH_VIEW]
T_WAIT = TYPE_CODES["timed_wait"]
N_INTERACTIONS = len(INTERACTIONS)
KIND_CODES = {k: i for i, k in enumerate(FEEDBACK_KINDS)}

MAX_MASK_RECTS = 61
"""A machine's distinct rects (components and dashboard regions) that fit a point mask
(an int64, one bit for 'in range'). Machines with more are replayed by the scalar path."""
MAX_COMPONENTS = 62
"""Components that fit the int64 hit mask of the repetition key (same fallback)."""
SITUATION_BITS = 16
POINT_BITS = 24
ACTION_SHIFT = SITUATION_BITS + POINT_BITS
"""A step's memo key packs (action id, point id, situation id) into one int: the action id
(< ACTION_LIMIT < 2**20) from bit 40, the point id (< 2**24) from bit 16, the situation
(< 2**16, machines with more states are replayed by the scalar path) below."""
SETUP_LIMIT = 100_000
"""Task setups whose row values are kept (`ColumnarCache.setup`)."""
MEMO_LIMIT = 200_000
"""Step results memoised per machine; the memo is cleared when it grows past this."""
ACTION_LIMIT = 1_000_000
"""Distinct actions kept before the whole cache is reset."""


class Columns:
    """Append-only numpy columns of one table (capacity doubles). Single rows (`add`) are
    buffered in Python lists and written on the next read, one numpy write per column."""

    def __init__(self, **dtypes: Any) -> None:
        self.n = 0
        self._data = {name: np.zeros(16, dtype) for name, dtype in dtypes.items()}
        self._pending: list[tuple] = []

    def extend(self, **values: Any) -> int:
        """Append rows (one sequence per column, equal lengths); returns the first row id."""
        if self._pending:
            self._flush()
        k = len(next(iter(values.values())))
        start = self._grow(k)
        if k:
            for name, arr in self._data.items():
                arr[start : start + k] = values[name]
        return start

    def add(self, *row: Any) -> int:
        """Append one row (values in column order); returns its id."""
        self._pending.append(row)
        return self.n + len(self._pending) - 1

    def __len__(self) -> int:
        return self.n + len(self._pending)

    def fill(self, k: int, **values: Any) -> int:
        """Append `k` rows with one constant value per column."""
        return self.extend(**{name: np.full(k, v) for name, v in values.items()})

    def __getitem__(self, name: str) -> np.ndarray:
        if self._pending:
            self._flush()
        return self._data[name]  # rows past `n` are unused capacity

    def _grow(self, k: int) -> int:
        start = self.n
        need = start + k
        for name, arr in self._data.items():
            if need > len(arr):
                grown = np.zeros(max(need, 2 * len(arr)), arr.dtype)
                grown[:start] = arr[:start]
                self._data[name] = grown
        self.n = need
        return start

    def _flush(self) -> None:
        rows, self._pending = self._pending, []
        start = self._grow(len(rows))
        for arr, values in zip(self._data.values(), zip(*rows, strict=True), strict=True):
            arr[start : start + len(rows)] = values


class Names:
    """Strings -> small integer codes (code 0 is None)."""

    def __init__(self) -> None:
        self.values: list[str | None] = [None]
        self.codes: dict[str | None, int] = {None: 0}

    def code(self, value: str | None) -> int:
        got = self.codes.get(value)
        if got is None:
            got = self.codes[value] = len(self.values)
            self.values.append(value)
        return got


class ActionVocab:
    """Distinct parsed actions (type and normalised params) and parse failures -> ids."""

    def __init__(self, details: Names) -> None:
        self.detail_names = details
        self.ids: dict[tuple, int] = {}
        self.fast_ids: dict[str, int] = {}  # the columnar parser's keys -> id or -1
        self.types: list[str | None] = []
        self.is_interaction: list[bool] = []
        self.params: list[tuple[str, ...]] = []
        self.details: list[str | None] = []
        self.cols = Columns(tcode=np.int8, uses_coord=np.bool_, detail=np.int64)

    def __len__(self) -> int:
        return len(self.types)

    def of_action(self, kind: str, params: tuple[str, ...]) -> int:
        key = (kind, params)
        got = self.ids.get(key)
        if got is None:
            got = self.ids[key] = len(self.types)
            self.types.append(kind)
            self.is_interaction.append(kind in INTERACTIONS)
            self.params.append(params)
            self.details.append(None)
            uses = kind in INTERACTIONS or (kind == SWITCH_VIEW and params == (DASHBOARD,))
            self.cols.add(TYPE_CODES[kind], uses, 0)
        return got

    def of_failure(self, detail: str | None) -> int:
        key = (None, detail)
        got = self.ids.get(key)
        if got is None:
            got = self.ids[key] = len(self.types)
            self.types.append(None)
            self.is_interaction.append(False)
            self.params.append(())
            self.details.append(detail)
            self.cols.add(-1, False, self.detail_names.code(detail))
        return got

    def of_parsed(self, parsed: ParsedAction) -> int:
        a = parsed.action
        if parsed.ok and a is not None:
            return self.of_action(a.type, a.params)
        return self.of_failure(parsed.detail)

    def parsed(self, aid: int, x: float, y: float, has_coord: bool) -> ParsedAction:
        """A ParsedAction the simulator reads the same way as the original (texts omitted)."""
        kind = self.types[aid]
        if kind is None:
            return ParsedAction(False, None, self.details[aid], "", "")
        coord = (x, y) if has_coord else None
        return ParsedAction(True, Action(kind, coord, self.params[aid]), None, "", "")


class OutcomeVocab:
    """Distinct simulator outcomes -> ids, with what classification and the columns need."""

    def __init__(self, details: Names) -> None:
        self.detail_names = details
        self.ids: dict[tuple, int] = {}
        self.texts: list[str] = []
        self.kinds: list[str] = []
        self.details: list[str | None] = []
        self.components: list[str | None] = []
        self.entered_names: list[list[str]] = []
        self.entered: list[tuple[int, ...]] = []  # machine state ids
        self.cols = Columns(
            kind=np.int8,
            switched=np.bool_,
            unlocked_now=np.bool_,
            dangerous=np.bool_,
            detail=np.int64,
        )

    def of(self, mt: MachineTables, outcome: Outcome) -> int:
        """The id of an outcome. A transition's outcome is a function of the machine and
        the transition (`_step._apply`); the others carry no transition nor entered state."""
        tr = outcome.transition
        if tr is not None:
            key: tuple = (mt.gid, tr.source, tr.component, tr.index)
        else:
            key = (
                outcome.kind,
                outcome.text,
                outcome.detail,
                outcome.switched,
                outcome.unlocked_now,
            )
        got = self.ids.get(key)
        if got is None:
            got = self.ids[key] = len(self.texts)
            names = mt.machine.states
            self.texts.append(outcome.text)
            self.kinds.append(outcome.kind)
            self.details.append(outcome.detail)
            self.components.append(tr.component if tr is not None else None)
            self.entered_names.append([names[s] for s in outcome.entered])
            self.entered.append(outcome.entered)
            self.cols.add(
                KIND_CODES[outcome.kind],
                outcome.switched,
                outcome.unlocked_now,
                outcome.dangerous,
                self.detail_names.code(outcome.detail),
            )
        return got


class GoalBlock:
    """Tables of one (machine, goal): distances, target rects per (state, view), switch
    classes per state. `base` indexes the cache's per-(goal block, state) columns."""

    __slots__ = ("goal", "base", "dist_base")

    def __init__(self, goal: int, base: int, dist_base: int) -> None:
        self.goal = goal
        self.base = base  # first row in trect_* (n_states * N_VIEWS rows) / 9 = state rows
        self.dist_base = dist_base  # first row in dist / swmask (n_states rows)


class MachineTables:
    """What the columnar path knows about one compiled machine."""

    def __init__(self, cache: ColumnarCache, machine: Machine, gid: int) -> None:
        self.machine = machine
        self.gid = gid
        self.n_states = len(machine.states)
        self.state_names = machine.states
        self.has_dashboard = bool(machine.dashboard_regions)
        self.state_base = len(cache.state_names)
        cache.state_names.extend(machine.states)
        comps = machine.components()
        self.comp_names = comps
        rank = {c: i for i, c in enumerate(comps)}
        self.comp_base = len(cache.comp_names)
        cache.comp_names.extend(comps)
        # Point masks: every distinct rect a step's outcome can depend on.
        rects: dict[tuple[float, float, float, float], int] = {}
        for pairs in machine.component_rects.values():
            for _, r in pairs:
                rects.setdefault(r[:4], len(rects))
        for regions in machine.dashboard_regions.values():
            for r in regions:
                rects.setdefault(r[:4], len(rects))
        self.supported = (
            len(rects) <= MAX_MASK_RECTS
            and len(comps) <= MAX_COMPONENTS
            and self.n_states * N_VIEWS * 2 <= 1 << SITUATION_BITS
        )
        boxes = list(rects)
        # Per view code: the bits a step's outcome can depend on in that view (its
        # component rects, its dashboard regions, and bit 0: the point is in range).
        self.view_bits = [1] * N_VIEWS
        for view, pairs in machine.component_rects.items():
            for _, r in pairs:
                self.view_bits[VIEW_CODES[view]] |= 2 << rects[r[:4]]
        for view, regions in machine.dashboard_regions.items():
            for r in regions:
                self.view_bits[VIEW_CODES[view]] |= 2 << rects[r[:4]]
        self.mask_start = cache.mask_rects.extend(
            x0=[b[0] for b in boxes],
            y0=[b[1] for b in boxes],
            x1=[b[2] for b in boxes],
            y1=[b[3] for b in boxes],
            bit=[np.int64(1) << np.int64(i + 1) for i in range(len(boxes))],
        )
        self.mask_count = len(boxes)
        # Component rects per view, sorted by (component, rect) like `component_rects`.
        starts, counts = [], []
        for view in VIEW_ORDER:
            pairs = machine.component_rects.get(view, ())
            starts.append(
                cache.comp_rects.extend(
                    x0=[r[0] for _, r in pairs],
                    y0=[r[1] for _, r in pairs],
                    x1=[r[2] for _, r in pairs],
                    y1=[r[3] for _, r in pairs],
                    comp=[self.comp_base + rank[c] for c, _ in pairs],
                )
            )
            counts.append(len(pairs))
        cache.crect.extend(start=starts, count=counts)  # row gid * N_VIEWS + view
        self.memo: dict[int, int] = {}  # step key (see `step_keys`) | situation -> result
        self.canonical: dict[tuple[int, int, int], int] = {}  # see `_columnar_sim._resolve`
        self.effects: dict[tuple[int, bool, int, int], tuple[int, bool, int]] = {}
        self.target_misses: dict[tuple[int, ...], tuple[int, int]] = {}
        self.situations: list[tuple[int, int, bool]] = []  # (state, view code, unlocked)
        self._situation_ids: dict[tuple[int, int, bool], int] = {}
        self.goal_blocks: dict[int, GoalBlock] = {}
        self._c_opt_dyn: dict[tuple[int, str, bool, int], int | None] = {}

    def check_size(self) -> None:
        if len(self.memo) > MEMO_LIMIT:
            self.memo.clear()
        if len(self.canonical) > MEMO_LIMIT:
            self.canonical.clear()
        if len(self.effects) > MEMO_LIMIT:
            self.effects.clear()
        if len(self.target_misses) > MEMO_LIMIT:
            self.target_misses.clear()

    def c_opt_dynamic(self, state: int, view: str, unlocked: bool, goal: int) -> int | None:
        """`_plan.c_opt_dynamic`, memoised."""
        key = (state, view, unlocked, goal)
        if key not in self._c_opt_dyn:
            self._c_opt_dyn[key] = c_opt_dynamic(self.machine, state, view, unlocked, goal)
        return self._c_opt_dyn[key]

    def situation(self, state: int, view: int, unlocked: bool) -> int:
        """(state, view code, dashboard unlocked) -> a small id (< 2**SITUATION_BITS)."""
        key = (state, view, unlocked)
        got = self._situation_ids.get(key)
        if got is None:
            got = self._situation_ids[key] = len(self.situations)
            self.situations.append(key)
        return got

    def goal_block(self, cache: ColumnarCache, goal: int) -> GoalBlock:
        got = self.goal_blocks.get(goal)
        if got is None:
            n = self.n_states
            dist = distances(self.machine, goal)
            dist_base = cache.dist.extend(dist=list(dist), swmask=np.full(n, -2))
            base = cache.trect.fill(n * N_VIEWS, start=-1, count=0)
            got = self.goal_blocks[goal] = GoalBlock(goal, base, dist_base)
        return got

    def fill_targets(self, cache: ColumnarCache, gb: GoalBlock, state: int, view: int) -> None:
        """Target rects of (state, goal) in a view -> cache.target_rects (lazily, once)."""
        pairs = target_rects(self.machine, state, gb.goal, VIEW_ORDER[view])
        rank = {c: i for i, c in enumerate(self.comp_names)}
        start = cache.target_rects.extend(
            x0=[r[0] for _, r in pairs],
            y0=[r[1] for _, r in pairs],
            x1=[r[2] for _, r in pairs],
            y1=[r[3] for _, r in pairs],
            comp=[self.comp_base + rank[c] for c, _ in pairs],
        )
        row = gb.base + state * N_VIEWS + view
        cache.trect["start"][row] = start
        cache.trect["count"][row] = len(pairs)

    def fill_switch_mask(self, cache: ColumnarCache, gb: GoalBlock, state: int) -> None:
        """Bit v set when a target component of (state, goal) has a bbox in view v (PROTOCOL §5's
        P); -1 when the goal has no target components there (switch class null)."""
        targets = target_components(self.machine, state, gb.goal)
        if not targets:
            mask = -1
        else:
            scr = self.machine.state_component_rects
            mask = 0
            for view, code in VIEW_CODES.items():
                if any(c in targets for c in scr.get((state, view), {})):
                    mask |= 1 << code
        cache.dist["swmask"][gb.dist_base + state] = mask


class SetupInfo:
    """Per task setup (and machine): what the replay of its episodes takes from it."""

    def __init__(self, cache: ColumnarCache, setup: EpisodeSetup, mt: MachineTables) -> None:
        names = mt.machine.states
        self.setup = setup
        self.mt = mt
        self.start_state = setup.start_state
        self.start_view = VIEW_CODES[setup.initial_view]
        self.goals = list(setup.goals)
        blocks = [mt.goal_block(cache, g) for g in setup.goals]
        self.dist_base = [b.dist_base for b in blocks]
        self.trect_base = [b.base for b in blocks]
        self.goal_names = [names[g] for g in setup.goals]
        self.c_opt = list(setup.plan.c_opt)
        self.l_opt = sum(setup.plan.c_opt)
        optimal = list(dict.fromkeys(list(setup.reset_states) + list(setup.plan.states)))
        self.optimal_names = [names[s] for s in optimal]
        self.optimal = [mt.state_base + s for s in optimal]  # global ids, first-visit order
        self.reset = [mt.state_base + s for s in setup.reset_states]
        self.initial_state = names[setup.initial_state]


class ColumnarCache:
    """Per-process tables of the columnar replay (see the module docstring)."""

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        self.details = Names()
        self.actions = ActionVocab(self.details)
        self.outcomes = OutcomeVocab(self.details)
        self.state_names: list[str] = []
        self.machines: dict[int, MachineTables] = {}
        self.comp_names: list[str] = []
        self.mask_rects = Columns(
            x0=np.float64, y0=np.float64, x1=np.float64, y1=np.float64, bit=np.int64
        )
        self.comp_rects = Columns(
            x0=np.float64, y0=np.float64, x1=np.float64, y1=np.float64, comp=np.int64
        )
        self.target_rects = Columns(
            x0=np.float64, y0=np.float64, x1=np.float64, y1=np.float64, comp=np.int64
        )
        self.crect = Columns(start=np.int64, count=np.int64)
        self.dist = Columns(dist=np.int64, swmask=np.int64)
        self.trect = Columns(start=np.int64, count=np.int64)
        # Point keys (rect mask * 2 + in range, or -1) -> small ids; 0 is "no point".
        self.point_ids: dict[int, int] = {-1: 0}
        # Memoised step results, shared by all machines: (machine, next situation, outcome).
        self.failures: dict[int, int] = {}  # parse failure (action id) -> outcome id
        self.result_ids: dict[tuple[int, int, int], int] = {}
        self.result_next: list[int] = []  # next situation id
        self.result_entered: list[tuple[int, ...]] = []  # states entered
        self.results = Columns(
            state=np.int64,
            view=np.int64,
            unlocked=np.bool_,
            outcome=np.int64,
            entered_start=np.int64,  # the states entered, in `entered`
            entered_count=np.int64,
        )
        self.entered = Columns(state=np.int64)  # global state ids (MachineTables.state_base)
        self.setup_info: dict[int, SetupInfo] = {}
        # Arrow mirrors of the string vocabularies (codes -> columns with one `take`).
        lists = pa.list_(pa.string())
        self.state_array = Vocab(self.state_names)
        self.comp_array = Vocab(self.comp_names)
        self.detail_array = Vocab(self.details.values)
        self.action_type_array = Vocab(self.actions.types)
        self.params_array = Vocab(self.actions.params, lists)
        self.text_array = Vocab(self.outcomes.texts)
        self.component_array = Vocab(self.outcomes.components)
        self.entered_array = Vocab(self.outcomes.entered_names, lists)

    def tables(self, machine: Machine) -> MachineTables:
        got = self.machines.get(id(machine))
        if got is None:  # the entry keeps the machine alive, so its id is never reused
            got = MachineTables(self, machine, self.crect.n // N_VIEWS)
            self.machines[id(machine)] = got
        return got

    def check_size(self) -> None:
        """Called before a batch: keep memory bounded (memos: `MachineTables.check_size`)."""
        if len(self.actions) > ACTION_LIMIT or len(self.point_ids) >= 1 << POINT_BITS:
            self.reset()

    def setup(self, setup: EpisodeSetup, machine: Machine) -> SetupInfo:
        """What the replay takes from a task's setup, computed once."""
        got = self.setup_info.get(id(setup))
        if got is None or got.setup is not setup or got.mt.machine is not machine:
            if len(self.setup_info) >= SETUP_LIMIT:
                self.setup_info.clear()
            got = self.setup_info[id(setup)] = SetupInfo(self, setup, self.tables(machine))
        return got

    def result(self, mt: MachineTables, situation: int, outcome_id: int, entered) -> int:
        """Id of a step result (what the memo stores)."""
        key = (mt.gid, situation, outcome_id)
        got = self.result_ids.get(key)
        if got is None:
            got = self.result_ids[key] = len(self.result_next)
            self.result_next.append(situation)
            self.result_entered.append(entered)
            state, view, unlocked = mt.situations[situation]
            start = len(self.entered)
            for s in entered:
                self.entered.add(mt.state_base + s)
            self.results.add(state, view, unlocked, outcome_id, start, len(entered))
        return got
