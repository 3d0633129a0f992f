"""The sequential part of the columnar replay: device state, view, dashboard, goals, budgets
and termination, one episode at a time (PROTOCOL §3), recording one integer per step.

The simulator itself is `replay.step`, called once per distinct situation: its result
depends only on the situation (state, view, dashboard unlocked), the action, and which of
the machine's rects (component bboxes of every view, dashboard regions) contain the point
and whether it lies in 0..1000. So results are memoised per machine under one int key
packing (action id, point id, situation id) (`step_keys`); a result id gives the next
situation, the outcome and the states entered (`ColumnarCache.result`).

Budgets and termination follow `replay_episode` exactly, but are computed at the few
steps where something can happen: `B_local` only changes by -1 per step between goal
completions, so the step at which a budget runs out is known in advance (`B - k`, exact in
floats while |B| < 2**52; larger budgets go to the scalar path), and the loop only stops at
completions and at that step.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import ceil

import numpy as np

from ..semantics._episode import EpisodeSetup, advance_goals, refreshed_budget
from ..semantics._step import SimState, step
from ..semantics._vocab import SWITCH_VIEW, VIEW_ORDER
from ._columnar_arrow import ragged_rows
from ._columnar_tables import (
    ACTION_SHIFT,
    SITUATION_BITS,
    VIEW_CODES,
    ColumnarCache,
    MachineTables,
)

EXACT_BUDGET = float(2**52)
"""Budgets below this are decremented exactly (see the module docstring)."""


@dataclass(slots=True)
class EpisodeSim:
    """What the loop found for one episode, besides the result id of each scored step."""

    termination: str | None
    taken: int  # scored steps
    goals_completed: int
    started: list[int | None]
    completed_at: list[int | None]
    dyn: list[int | None]
    budget_global: float
    events: list[tuple[int, int, float]]  # (step, goals completed, B_local after) per completion
    budget_local: float  # B_local at reset


def step_keys(
    cache: ColumnarCache,
    mts: list[MachineTables],
    step_machine: np.ndarray,
    aid: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    has_coord: np.ndarray,
) -> tuple[list[int], list[int]]:
    """Per step, the memo key without its situation (action id and point id, shifted), and
    the point key itself.

    The point key is the mask of the step's machine's rects containing (x, y), times 2,
    plus 1 when the point lies in 0..1000; -1 when the action reads no coordinate (only
    interactions and a switch to the dashboard do)."""
    n = len(x)
    keys = np.full(n, -1, np.int64)
    idx = np.flatnonzero(cache.actions.cols["uses_coord"][aid] & has_coord)
    if len(idx):
        starts = np.array([mt.mask_start for mt in mts], np.int64)[step_machine[idx]]
        counts = np.array([mt.mask_count for mt in mts], np.int64)[step_machine[idx]]
        px, py = x[idx], y[idx]
        in_range = (px >= 0.0) & (px <= 1000.0) & (py >= 0.0) & (py <= 1000.0)
        keys[idx] = in_range
        if counts.any():
            first = np.cumsum(counts) - counts
            owner, rect = ragged_rows(starts, counts)
            r = cache.mask_rects
            qx, qy = px[owner], py[owner]
            inside = (r["x0"][rect] <= qx) & (qx <= r["x1"][rect])
            inside &= (r["y0"][rect] <= qy) & (qy <= r["y1"][rect])
            bits = np.where(inside, r["bit"][rect], 0)
            nonempty = counts > 0
            masks = np.bitwise_or.reduceat(bits, first[nonempty])
            keys[idx[nonempty]] |= masks
    uniq, inverse = np.unique(keys, return_inverse=True)
    ids = cache.point_ids
    pid = np.array([ids.setdefault(k, len(ids)) for k in uniq.tolist()], np.int64)[inverse]
    return ((aid << ACTION_SHIFT) | (pid << SITUATION_BITS)).tolist(), keys.tolist()


def simulate_episode(
    cache: ColumnarCache,
    mt: MachineTables,
    setup: EpisodeSetup,
    lam: float,
    keys: list[int],
    points: list[int],
    aids: list[int],
    x: list[float],
    y: list[float],
    has_coord: list[bool],
    begin: int,
    end: int,
    rids: list[int],
) -> EpisodeSim:
    """Replay steps `begin..end` of the batch, appending the result id of each scored step
    to `rids`; stops at termination (the remaining steps are truncated)."""
    memo_get = mt.memo.get
    next_of = cache.result_next
    entered_of = cache.result_entered
    record = rids.append
    goals = setup.goals
    n_goals = len(goals)
    c_opt = setup.plan.c_opt
    budget_global = lam * sum(c_opt)
    k_global = ceil(budget_global) - 1  # the first step k with k + 1 >= B_global
    b_base = b_start = lam * c_opt[0]  # B_local after step `base_k` (before any step: -1)
    base_k = -1
    k_local = base_k + ceil(b_base)  # the first step with B_local <= 0
    situation = mt.situation(setup.start_state, VIEW_CODES[setup.initial_view], False)
    started: list[int | None] = [None] * n_goals
    completed_at: list[int | None] = [None] * n_goals
    dyn: list[int | None] = [None] * n_goals
    started[0] = 0
    dyn[0] = mt.c_opt_dynamic(setup.start_state, setup.initial_view, False, goals[0])
    events: list[tuple[int, int, float]] = []
    current = 0
    goal = goals[0]
    termination = None
    start = begin
    while True:
        deadline = begin + min(k_global, k_local)  # a budget runs out at this step
        stop = deadline + 1 if deadline < end else end
        for i in range(start, stop):
            rid = memo_get(keys[i] | situation)
            if rid is None:
                rid = _resolve(
                    cache, mt, keys[i] | situation, situation, points, aids, x, y, has_coord, i
                )
            record(rid)
            situation = next_of[rid]
            if goal in entered_of[rid]:
                break
        else:  # no goal completed up to `stop`
            if stop == end and deadline >= end:
                taken = end - begin  # the log ended first
            else:
                taken = deadline - begin + 1
                termination = "budget_global" if taken >= budget_global else "budget_local"
            break
        # Step i completed the current goal (and maybe more): PROTOCOL §3 bookkeeping.
        k = i - begin
        goal_index = current
        current = advance_goals(entered_of[rid], goals, current, k, started, completed_at, dyn)
        b = refreshed_budget(b_base - (k - base_k), lam, c_opt, goal_index, current)
        events.append((i, current - goal_index, b))
        b_base, base_k = b, k
        taken = k + 1
        if current >= n_goals:
            termination = "success"
            break
        state, view, unlocked = mt.situations[situation]
        goal = goals[current]
        dyn[current] = mt.c_opt_dynamic(state, VIEW_ORDER[view], unlocked, goal)
        if taken >= budget_global:
            termination = "budget_global"
            break
        if b <= 0:
            termination = "budget_local"
            break
        k_local = base_k + ceil(b)
        start = i + 1
    return EpisodeSim(
        termination,
        taken,
        current,
        started,
        completed_at,
        dyn,
        budget_global,
        events,
        b_start,
    )


def _resolve(
    cache: ColumnarCache,
    mt: MachineTables,
    key: int,
    situation: int,
    points: list[int],
    aids: list[int],
    x: list[float],
    y: list[float],
    has_coord: list[bool],
    i: int,
) -> int:
    """The result of a step key not met before, from what `step` actually reads:

    - the point only through the rects and regions of the situation's view (and whether it
      is in range): the point key is restricted to the view's bits;
    - not the device state, for a parse failure, a `Switch_view`, and an interaction whose
      point is in no rect or region of the view (or that has none: an invalid action or a
      null effect, whatever the action, so not even the action is read): their effect on
      (view, dashboard) and their outcome are memoised per (view, dashboard, action, point);
    - for the rest, per (situation, action, point).
    The simulator runs once per new such key."""
    state, view, unlocked = mt.situations[situation]
    aid = aids[i]
    point = points[i]
    where = point & mt.view_bits[view] if point >= 0 else -1
    kind = cache.actions.types[aid]
    if kind is None:  # a parse failure: nothing changes, the outcome depends on nothing else
        oc = cache.failures.get(aid)
        if oc is None:
            _, oc = _simulate(cache, mt, state, view, unlocked, aid, x[i], y[i], has_coord[i])
            cache.failures[aid] = oc
        rid = cache.result(mt, situation, oc, ())
    elif kind == SWITCH_VIEW or (cache.actions.is_interaction[aid] and where <= 1):
        effect_key = (view, unlocked, aid if kind == SWITCH_VIEW else -1, where)
        effect = mt.effects.get(effect_key)
        if effect is None:
            after, oc = _simulate(cache, mt, state, view, unlocked, aid, x[i], y[i], has_coord[i])
            effect = mt.effects[effect_key] = (VIEW_CODES[after.view], after.unlocked, oc)
        nxt = mt.situation(state, effect[0], effect[1])
        rid = cache.result(mt, nxt, effect[2], ())
    else:
        canonical = (situation, aid, where)
        rid = mt.canonical.get(canonical)
        if rid is None:
            after, oc = _simulate(cache, mt, state, view, unlocked, aid, x[i], y[i], has_coord[i])
            nxt = mt.situation(after.state, VIEW_CODES[after.view], after.unlocked)
            rid = cache.result(mt, nxt, oc, cache.outcomes.entered[oc])
            mt.canonical[canonical] = rid
    mt.memo[key] = rid
    return rid


def _simulate(
    cache: ColumnarCache,
    mt: MachineTables,
    state: int,
    view: int,
    unlocked: bool,
    aid: int,
    x: float,
    y: float,
    has_coord: bool,
) -> tuple[SimState, int]:
    parsed = cache.actions.parsed(aid, x, y, has_coord)
    after, outcome = step(mt.machine, SimState(state, VIEW_ORDER[view], unlocked), parsed)
    return after, cache.outcomes.of(mt, outcome)


def scored_progress(
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
