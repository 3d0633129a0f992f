"""Columnar (batch) replay: many episodes at once, steps built as Arrow columns.

Produces exactly the rows `replay_episode` produces (the reference implementation), much
faster, by splitting the work by nature:

1. parse every step of the batch at once (`_columnar_parse`: polars for the common shape,
   the scalar parser for the rest);
2. per episode, a lean sequential loop over what is inherently sequential (state, view,
   dashboard, goals, budgets, termination), the simulator memoised per machine
   (`_columnar_sim`), recording integers;
3. classify all scored steps with array operations (`_columnar_classify`);
4. build the Arrow columns from numpy arrays and integer codes (`_columnar_arrow`), with
   no per-row Python tuples.

Episodes this path does not cover (a machine with more rects or components than an int64
mask holds, a non-finite coordinate) are replayed by `replay_episode` and merged in order.
`tests/replay/test_columnar.py` checks the equality, table against table.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import chain

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from . import _columnar_arrow as arw
from ._columnar_classify import Classified, Scored, classify
from ._columnar_parse import ParsedSteps, parse_steps
from ._columnar_sim import EXACT_BUDGET, EpisodeSim, simulate_episode, step_keys
from ._columnar_tables import N_VIEWS, VIEW_CODES, ColumnarCache, MachineTables
from ._episode import EpisodeSetup, replay_episode, timestamp_seconds
from ._machine import Machine
from ._plan import INF
from ._records import EpisodeLog, Task
from ._rows import EpisodeRow, GoalRow, StepRow
from ._tables import arrow_schema, rows_to_table
from ._vocab import ERROR_GROUPS, ERROR_TYPES, FEEDBACK_KINDS, SWITCH_CLASSES, VIEW_ORDER

_DIVERGENCE_FIELDS = pa.array(["feedback", "state", "view"], pa.string())
_FEEDBACK_KINDS = pa.array(FEEDBACK_KINDS, pa.string())
_VIEWS = pa.array(VIEW_ORDER, pa.string())
_ERROR_TYPES = pa.array(ERROR_TYPES, pa.string())
_ERROR_GROUPS = pa.array([ERROR_GROUPS[t] for t in ERROR_TYPES], pa.string())
_SWITCH_CLASSES = pa.array(SWITCH_CLASSES, pa.string())
_NO_STRINGS = pa.scalar([], pa.list_(pa.string()))


@dataclass(frozen=True)
class EpisodeInput:
    """One decoded, set-up episode to replay."""

    machine: Machine
    task: Task
    setup: EpisodeSetup
    log: EpisodeLog
    lam: float


@dataclass
class ColumnarBatch:
    """The three tables of a batch, rows in episode order (like the scalar path's)."""

    steps: pa.Table
    episodes: pa.Table
    goals: pa.Table
    step_counts: list[int]  # per episode
    goal_counts: list[int]
    fast_parsed: int = 0  # steps parsed by the vectorised parser
    scalar_episodes: int = 0  # episodes replayed by `replay_episode`


def replay_columnar(
    cache: ColumnarCache,
    episodes: list[EpisodeInput],
    *,
    run_id: str,
    model: str,
    agent_kind: str,
) -> ColumnarBatch:
    """Replay episodes; the tables equal `rows_to_table` of the scalar rows, concatenated."""
    cache.check_size()
    counts = [len(e.log.steps) for e in episodes]
    steps = [s for e in episodes for s in e.log.steps]
    parsed = parse_steps(steps, cache.actions)
    head = (run_id, model, agent_kind)
    scalar = _needs_scalar(cache, episodes, counts, parsed)
    if not scalar:
        batch = _replay(cache, episodes, counts, parsed, head)
        batch.fast_parsed = parsed.fast
        return batch
    return _merge(cache, episodes, counts, parsed, head, scalar)


def _needs_scalar(
    cache: ColumnarCache, episodes: list[EpisodeInput], counts: list[int], parsed: ParsedSteps
) -> list[int]:
    """Episodes for the scalar path: a machine too large for the int masks, a non-finite
    coordinate, or a budget too large to be decremented exactly in floats."""
    bad = parsed.has_coord & ~(np.isfinite(parsed.x) & np.isfinite(parsed.y))
    odd = set()
    if bad.any():
        odd = set(np.repeat(np.arange(len(counts)), counts)[bad].tolist())
    return [
        i
        for i, e in enumerate(episodes)
        if i in odd
        or not cache.tables(e.machine).supported
        or not float(e.lam) * sum(e.setup.plan.c_opt) < EXACT_BUDGET
    ]


def _merge(
    cache: ColumnarCache,
    episodes: list[EpisodeInput],
    counts: list[int],
    parsed: ParsedSteps,
    head: tuple[str, str, str],
    scalar: list[int],
) -> ColumnarBatch:
    """Columnar tables for most episodes, scalar rows for the others, in episode order."""
    odd = set(scalar)
    keep = [i for i in range(len(episodes)) if i not in odd]
    starts = np.cumsum([0] + counts)
    rows = np.concatenate(
        [np.arange(starts[i], starts[i + 1]) for i in keep] + [np.zeros(0, np.int64)]
    )
    sub = ParsedSteps(
        parsed.aid[rows],
        parsed.x[rows],
        parsed.y[rows],
        parsed.has_coord[rows],
        arw.take_rows(parsed.output, rows),
        arw.take_rows(parsed.action_raw, rows),
        arw.take_rows(parsed.thinking, rows),
        0,
    )
    fast = _replay(cache, [episodes[i] for i in keep], [counts[i] for i in keep], sub, head)
    results = [
        replay_episode(
            episodes[i].machine,
            episodes[i].task,
            episodes[i].log,
            lam=episodes[i].lam,
            run_id=head[0],
            model=head[1],
            agent_kind=head[2],
            setup=episodes[i].setup,
        )
        for i in scalar
    ]
    slow = ColumnarBatch(
        rows_to_table([t for r in results for t in r.step_tuples], StepRow),
        rows_to_table([r.episode for r in results], EpisodeRow),
        rows_to_table([g for r in results for g in r.goals], GoalRow),
        [len(r.step_tuples) for r in results],
        [len(r.goals) for r in results],
    )
    order = keep + scalar  # batch position of each part's episodes, fast ones first
    step_counts = fast.step_counts + slow.step_counts
    goal_counts = fast.goal_counts + slow.goal_counts
    by_position = sorted(range(len(order)), key=order.__getitem__)
    return ColumnarBatch(
        _reorder(fast.steps, slow.steps, step_counts, by_position),
        _reorder(fast.episodes, slow.episodes, [1] * len(order), by_position),
        _reorder(fast.goals, slow.goals, goal_counts, by_position),
        [step_counts[j] for j in by_position],
        [goal_counts[j] for j in by_position],
        parsed.fast,
        len(scalar),
    )


def _reorder(a: pa.Table, b: pa.Table, counts: list[int], by_position: list[int]) -> pa.Table:
    """Rows of [a; b] grouped per episode (`counts` in part order), episodes re-ordered."""
    starts = np.cumsum([0] + counts)
    rows = [np.arange(starts[j], starts[j + 1]) for j in by_position]
    table = pa.concat_tables([a, b]).take(pa.array(np.concatenate(rows + [np.zeros(0, int)])))
    return table.combine_chunks()


def _replay(
    cache: ColumnarCache,
    episodes: list[EpisodeInput],
    counts: list[int],
    parsed: ParsedSteps,
    head: tuple[str, str, str],
) -> ColumnarBatch:
    n = len(parsed.aid)
    n_eps = len(episodes)
    mts: list[MachineTables] = []
    where: dict[int, int] = {}
    ep_machine = np.zeros(n_eps, np.int64)
    for e, ep in enumerate(episodes):
        mt = cache.tables(ep.machine)
        j = where.get(mt.gid)
        if j is None:
            j = where[mt.gid] = len(mts)
            mts.append(mt)
            mt.check_size()
        ep_machine[e] = j
    step_ep = np.repeat(np.arange(n_eps), counts)
    step_machine = ep_machine[step_ep]

    # 2. The sequential loop.
    keys, points = step_keys(
        cache, mts, step_machine, parsed.aid, parsed.x, parsed.y, parsed.has_coord
    )
    aids, xs, ys = parsed.aid.tolist(), parsed.x.tolist(), parsed.y.tolist()
    has_coord = parsed.has_coord.tolist()
    rids: list[int] = []
    sims = []
    begin = 0
    for e, ep in enumerate(episodes):
        end = begin + counts[e]
        sims.append(
            simulate_episode(
                cache,
                mts[ep_machine[e]],
                ep.setup,
                float(ep.lam),
                keys,
                points,
                aids,
                xs,
                ys,
                has_coord,
                begin,
                end,
                rids,
            )
        )
        begin = end

    # Scored steps (the first `taken` of each episode) and their situation.
    taken = np.array([s.taken for s in sims], np.int64)
    ep_start = np.cumsum(np.concatenate([[0], counts]))[:-1].astype(np.int64)
    step_k = np.arange(n) - ep_start[step_ep]
    scored = np.flatnonzero(step_k < taken[step_ep])
    rid = np.array(rids, np.int64)
    res = cache.results
    s1, v1, unlocked, outcome = (res[c][rid] for c in ("state", "view", "unlocked", "outcome"))
    completed, goal_index, b_local = _goal_progress(sims, step_ep[scored], step_k[scored], scored)
    sep = step_ep[scored]
    first = step_k[scored] == 0
    start_state = np.array([e.setup.start_state for e in episodes], np.int64)
    start_view = np.array([VIEW_CODES[e.setup.initial_view] for e in episodes], np.int64)
    s0 = np.where(first, start_state[sep], np.roll(s1, 1))
    v0 = np.where(first, start_view[sep], np.roll(v1, 1))
    goal_counts = [len(e.setup.goals) for e in episodes]
    goal_start = np.cumsum([0] + goal_counts)[:-1].astype(np.int64)
    goal_states, dist_base, trect_base = [], [], []
    for e, ep in enumerate(episodes):
        mt = mts[ep_machine[e]]
        for g in ep.setup.goals:
            gb = mt.goal_block(cache, g)
            goal_states.append(g)
            dist_base.append(gb.dist_base)
            trect_base.append(gb.base)
    goal_slot = goal_start[sep] + goal_index
    sc = Scored(
        ep=sep,
        machine=ep_machine[sep],
        goal_index=goal_index,
        goal=np.array(goal_states, np.int64)[goal_slot],
        dist_base=np.array(dist_base, np.int64)[goal_slot],
        trect_base=np.array(trect_base, np.int64)[goal_slot],
        s0=s0,
        s1=s1,
        v0=v0,
        v1=v1,
        outcome=outcome,
        completed=completed,
        aid=parsed.aid[scored],
        x=parsed.x[scored],
        y=parsed.y[scored],
        has_coord=parsed.has_coord[scored],
    )

    # 3. Classification.
    cl = classify(cache, mts, sc)

    # 4. Columns.
    budget_global = np.array([s.budget_global for s in sims])
    cols, diverged = _step_columns(
        cache, episodes, parsed, step_ep, step_k, scored, sc, cl, head, unlocked, b_local,
        budget_global, mts,
    )  # fmt: skip
    switched = cache.outcomes.cols["switched"][outcome]
    steps_used = np.bincount(goal_slot, minlength=sum(goal_counts))
    goal_switches = np.bincount(goal_slot, weights=switched, minlength=sum(goal_counts))
    steps_table = pa.Table.from_arrays(
        [cols[f.name] for f in arrow_schema(StepRow)], schema=arrow_schema(StepRow)
    )
    entered_of = cache.result_entered
    entered, at = [], 0
    for sim in sims:
        entered.append([entered_of[r] for r in rids[at : at + sim.taken]])
        at += sim.taken
    episode_rows, goal_rows = _episode_rows(
        episodes, counts, sims, entered, head, goal_start, steps_used, goal_switches, diverged
    )
    return ColumnarBatch(
        steps_table,
        rows_to_table(episode_rows, EpisodeRow),
        rows_to_table(goal_rows, GoalRow),
        counts,
        goal_counts,
    )


def _goal_progress(
    sims: list[EpisodeSim], ep: np.ndarray, k: np.ndarray, scored: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per scored step: goals completed, goal index, B_local after the step (from the
    completion events the loop recorded; between them B_local drops by 1 per step)."""
    n = len(ep)
    position = np.full(int(scored[-1]) + 1 if n else 0, -1, np.int64)
    position[scored] = np.arange(n)
    completed = np.zeros(n, np.int64)
    base_value = np.zeros(n)
    base_k = np.full(n, -1, np.int64)
    marked = np.zeros(n, np.bool_)
    first = np.flatnonzero(k == 0)
    marked[first] = True
    base_value[first] = [sims[e].budget_local for e in ep[first].tolist()]
    events = [ev for sim in sims for ev in sim.events]
    if events:
        rows, counts, values = zip(*events, strict=True)
        at = position[np.array(rows, np.int64)]
        completed[at] = counts
        marked[at] = True
        base_value[at] = values
        base_k[at] = k[at]
    source = np.maximum.accumulate(np.where(marked, np.arange(n), 0))
    b_local = base_value[source] - (k - base_k[source])
    before = np.cumsum(completed) - completed  # goals completed before each step (batch)
    episode_first = np.maximum.accumulate(np.where(k == 0, np.arange(n), 0))
    return completed, before - before[episode_first], b_local


def _step_columns(
    cache: ColumnarCache,
    episodes: list[EpisodeInput],
    parsed: ParsedSteps,
    step_ep: np.ndarray,
    step_k: np.ndarray,
    scored: np.ndarray,
    sc: Scored,
    cl: Classified,
    head: tuple[str, str, str],
    unlocked: np.ndarray,
    b_local: np.ndarray,
    budget_global: np.ndarray,
    mts: list[MachineTables],
) -> tuple[dict[str, pa.Array], np.ndarray]:
    """Every StepRow column, by name; and the diverged steps per episode."""
    n = len(step_ep)
    actions, outcomes = cache.actions, cache.outcomes
    live = np.zeros(n, np.bool_)
    live[scored] = True

    def full(values: np.ndarray, fill: object = 0) -> np.ndarray:
        return arw.scatter(n, scored, values, fill)

    def opt(values: np.ndarray, type_: pa.DataType, valid: np.ndarray | None = None):
        fill = False if type_ == pa.bool_() else 0
        return arw.numbers(full(values, fill), type_, live if valid is None else full(valid, False))

    def codes(values: np.ndarray) -> np.ndarray:
        return full(values, -1)

    def per_episode(values: list) -> pa.Array:
        return pa.array(values, pa.string()).take(pa.array(step_ep))

    steps = [s for e in episodes for s in e.log.steps]
    goal_names = [e.machine.states[g] for e in episodes for g in e.setup.goals]
    goal_start = np.cumsum([0] + [len(e.setup.goals) for e in episodes])[:-1]
    state_base = np.array([mt.state_base for mt in mts], np.int64)[sc.machine]
    has_dashboard = np.array([mt.has_dashboard for mt in mts], np.bool_)[sc.machine]
    oc = codes(sc.outcome)
    kinds = outcomes.cols["kind"][sc.outcome].astype(np.int64)

    feedback_kind = _FEEDBACK_KINDS.take(pa.array(codes(kinds), mask=~live))
    feedback_text = cache.text_array.take(oc)
    state_after = cache.state_array.take(codes(state_base + sc.s1))
    view_after = _VIEWS.take(pa.array(codes(sc.v1), mask=~live))
    recorded_feedback = pa.array([s.feedback for s in steps], pa.string())
    recorded_state = pa.array([s.state for s in steps], pa.string())
    recorded_view = pa.array([s.view for s in steps], pa.string())
    diverged, diverged_counts, diverged_values, diverged_steps = _divergence(
        live, step_ep, len(episodes), recorded_feedback, recorded_state, recorded_view,
        feedback_kind, feedback_text, state_after, view_after,
    )  # fmt: skip
    timestamps = [
        t if t.__class__ is float or t is None else timestamp_seconds(t)
        for t in (s.timestamp for s in steps)
    ]
    hit_counts = full(np.diff(cl.hit_offsets))
    error_type = codes(cl.error_type)
    columns = {
        "run_id": pa.array([head[0]], pa.string()).take(pa.array(np.zeros(n, np.int64))),
        "model": pa.array([head[1]], pa.string()).take(pa.array(np.zeros(n, np.int64))),
        "agent_kind": pa.array([head[2]], pa.string()).take(pa.array(np.zeros(n, np.int64))),
        "episode_id": per_episode([e.task.episode_id for e in episodes]),
        "device_id": per_episode([e.machine.device_id for e in episodes]),
        "category": per_episode([e.machine.category for e in episodes]),
        "step": pa.array(step_k, pa.int64()),
        "goal_index": opt(sc.goal_index, pa.int64()),
        "goal_state": pa.array(goal_names, pa.string()).take(
            pa.array(codes(goal_start[sc.ep] + sc.goal_index), mask=~live)
        ),
        "view_before": _VIEWS.take(pa.array(codes(sc.v0), mask=~live)),
        "view_after": view_after,
        "dashboard_unlocked": opt(unlocked, pa.bool_(), has_dashboard),
        "action_type": cache.action_type_array.take(parsed.aid),
        "action_raw": parsed.action_raw,
        "thinking": parsed.thinking,
        "output": parsed.output,
        "x": arw.numbers(parsed.x, pa.float64(), parsed.has_coord),
        "y": arw.numbers(parsed.y, pa.float64(), parsed.has_coord),
        "params": cache.params_array.take(parsed.aid),
        "parse_ok": pa.array(actions.cols["tcode"][parsed.aid] >= 0, pa.bool_()),
        "parse_detail": cache.detail_array.take(actions.cols["detail"][parsed.aid]),
        "feedback_kind": feedback_kind,
        "feedback_text": feedback_text,
        "state_before": cache.state_array.take(codes(state_base + sc.s0)),
        "state_after": state_after,
        "states_entered": pc.fill_null(cache.entered_array.take(oc), _NO_STRINGS),
        "transition_component": cache.component_array.take(oc),
        "dangerous": opt(outcomes.cols["dangerous"][sc.outcome], pa.bool_()),
        "is_switch": opt(outcomes.cols["switched"][sc.outcome], pa.bool_()),
        "completed_goals": opt(sc.completed, pa.int64()),
        "is_interaction": opt(cl.is_interaction, pa.bool_()),
        "hit_component": opt(cl.hit_component, pa.bool_(), cl.is_interaction),
        "hit_target": opt(cl.hit_target, pa.bool_(), cl.is_interaction),
        "hit_components": arw.ragged_strings(hit_counts, cache.comp_array.take(cl.hit_values)),
        "nearest_target": cache.comp_array.take(codes(cl.nearest)),
        "progress": opt(cl.progress, pa.bool_()),
        "dist_before": opt(cl.dist_before, pa.int64(), cl.dist_before < INF),
        "dist_after": opt(cl.dist_after, pa.int64(), cl.dist_after < INF),
        "error_type": _ERROR_TYPES.take(pa.array(error_type, mask=error_type < 0)),
        "error_detail": cache.detail_array.take(full(cl.error_detail)),
        "error_group": _ERROR_GROUPS.take(pa.array(error_type, mask=error_type < 0)),
        "switch_class": _SWITCH_CLASSES.take(
            pa.array(codes(cl.switch_class), mask=codes(cl.switch_class) < 0)
        ),
        "repetitive": opt(cl.repetitive, pa.bool_()),
        "eer_valid": opt(cl.eer_valid, pa.bool_(), ~cl.is_switch_view),
        "distance": opt(cl.distance, pa.float64(), ~np.isnan(cl.distance)),
        "weight": opt(cl.weight, pa.int64(), cl.weight > 0),
        "budget_global_left": opt(budget_global[sc.ep] - (step_k[scored] + 1), pa.float64()),
        "budget_local_left": opt(b_local.astype(np.float64), pa.float64()),
        "truncated": pa.array(~live, pa.bool_()),
        "recorded_feedback": recorded_feedback,
        "recorded_state": recorded_state,
        "recorded_view": recorded_view,
        "diverged": diverged,
        "diverged_fields": arw.ragged_strings(diverged_counts, diverged_values),
        "timestamp": pa.array(timestamps, pa.float64()),
    }
    return columns, diverged_steps


def _divergence(
    live: np.ndarray,
    step_ep: np.ndarray,
    n_eps: int,
    recorded_feedback: pa.Array,
    recorded_state: pa.Array,
    recorded_view: pa.Array,
    feedback_kind: pa.Array,
    feedback_text: pa.Array,
    state_after: pa.Array,
    view_after: pa.Array,
) -> tuple[pa.Array, np.ndarray, pa.Array, np.ndarray]:
    """SEMANTICS 'Divergence' on scored steps: (diverged, field counts, field names,
    diverged steps per episode)."""

    def differs(recorded: pa.Array, mine: pa.Array) -> np.ndarray:
        return pc.fill_null(pc.not_equal(recorded, mine), False).to_numpy(zero_copy_only=False)

    is_kind = pc.is_in(recorded_feedback, pa.array(FEEDBACK_KINDS, pa.string()))
    mine = pc.if_else(pc.fill_null(is_kind, False), feedback_kind, feedback_text)
    lowered = _lower(recorded_view)
    fields = np.stack(
        [
            differs(recorded_feedback, mine),
            differs(recorded_state, state_after),
            differs(lowered, view_after),
        ],
        axis=1,
    )
    fields &= live[:, None]
    recorded = (
        recorded_feedback.is_valid().to_numpy(zero_copy_only=False)
        | recorded_state.is_valid().to_numpy(zero_copy_only=False)
        | recorded_view.is_valid().to_numpy(zero_copy_only=False)
    ) & live
    counts = fields.sum(axis=1)
    flat = np.flatnonzero(fields.ravel()) % 3
    diverged = counts > 0
    per_episode = np.bincount(step_ep, weights=diverged, minlength=n_eps).astype(np.int64)
    return (
        arw.numbers(diverged, pa.bool_(), recorded),
        counts,
        _DIVERGENCE_FIELDS.take(pa.array(flat, pa.int64())),
        per_episode,
    )


def _lower(values: pa.Array) -> pa.Array:
    """Python's `str.lower()` of each string (on the distinct values only)."""
    encoded = pc.dictionary_encode(values)
    lowered = pa.array(
        [v.lower() if v is not None else None for v in encoded.dictionary.to_pylist()],
        pa.string(),
    )
    return lowered.take(encoded.indices)


def _first_visit_order(states: list[int]) -> list[int]:
    return list(dict.fromkeys(states))


def _episode_rows(
    episodes: list[EpisodeInput],
    counts: list[int],
    sims: list[EpisodeSim],
    entered: list[list[tuple[int, ...]]],
    head: tuple[str, str, str],
    goal_start: np.ndarray,
    steps_used: np.ndarray,
    goal_switches: np.ndarray,
    diverged: np.ndarray,
) -> tuple[list[tuple], list[tuple]]:
    """Episode and goal rows as tuples in EpisodeRow / GoalRow field order (the epilogue
    of `replay_episode`)."""
    episode_rows: list[tuple] = []
    goal_rows: list[tuple] = []
    used_all = steps_used.tolist()
    switches_all = goal_switches.astype(np.int64).tolist()
    for e, ep in enumerate(episodes):
        sim = sims[e]
        setup, task, machine = ep.setup, ep.task, ep.machine
        names = machine.states
        goals = setup.goals
        n_goals = len(goals)
        c_opt = setup.plan.c_opt
        g0 = int(goal_start[e])
        used = used_all[g0 : g0 + n_goals]
        switches = switches_all[g0 : g0 + n_goals]
        common = head + (task.episode_id, machine.device_id, machine.category)
        goals_completed = sim.goals_completed
        success = goals_completed == n_goals
        l_opt = sum(c_opt)
        l_act = sim.taken
        spl = (l_opt / max(l_act, l_opt) if l_opt else 1.0) if success else 0.0
        visited = list(chain(setup.reset_states, *entered[e]))
        visited_set = set(visited)
        optimal_list = list(setup.reset_states) + list(setup.plan.states)
        optimal_set = set(optimal_list)
        state_f1 = 2.0 * len(visited_set & optimal_set) / (len(visited_set) + len(optimal_set))
        completed_at = sim.completed_at
        vsps_switches = sum(switches[g] for g in range(n_goals) if completed_at[g] is not None)
        episode_rows.append(
            (
                *common, n_goals, goals_completed, success, sim.termination or "log_ended",
                l_opt, l_act, spl, state_f1, sum(switches), vsps_switches,
                vsps_switches / goals_completed if goals_completed else None,
                counts[e], counts[e] - l_act, int(diverged[e]), float(ep.lam),
                sim.budget_global, names[setup.initial_state], setup.initial_view,
                [names[g] for g in goals], list(c_opt),
                list(task.c_opt) if task.c_opt is not None else None,
                [names[s] for s in _first_visit_order(visited)],
                [names[s] for s in _first_visit_order(optimal_list)],
            )
        )  # fmt: skip
        instructions = task.instructions
        dyn, started = sim.dyn, sim.started
        for g in range(n_goals):
            goal_rows.append(
                (
                    *common, n_goals, g, names[goals[g]],
                    instructions[g] if g < len(instructions) else None,
                    c_opt[g], dyn[g], started[g] is not None, completed_at[g] is not None,
                    started[g], completed_at[g], used[g], switches[g],
                    completed_at[g] is not None and dyn[g] is not None and used[g] <= dyn[g],
                )
            )  # fmt: skip
    return episode_rows, goal_rows


__all__ = ["ColumnarBatch", "ColumnarCache", "EpisodeInput", "N_VIEWS", "replay_columnar"]
