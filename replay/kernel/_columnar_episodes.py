"""The episode and goal tables of a columnar batch (the epilogue of `replay_episode`).

Per-episode and per-goal values come from the sequential loop (`EpisodeSim`) and the
per-step arrays; the visited states (first-visit order, State-F1) are computed for the
whole batch from the states each scored step entered.
"""

from __future__ import annotations

import numpy as np
import pyarrow as pa

from ..semantics._rows import EpisodeRow, GoalRow
from ..semantics._tables import arrow_schema
from ._columnar_arrow import ragged_rows, ragged_strings
from ._columnar_sim import EpisodeSim
from ._columnar_tables import ColumnarCache, SetupInfo

_INT_LIST = pa.list_(pa.int64())
_STR_LIST = pa.list_(pa.string())


def episode_tables(
    cache: ColumnarCache,
    infos: list[SetupInfo],
    episodes: list,
    sims: list[EpisodeSim],
    counts: list[int],
    head: tuple[str, str, str],
    scored_ep: np.ndarray,
    scored_rid: np.ndarray,
    goal_slot: np.ndarray,
    switched: np.ndarray,
    diverged: np.ndarray,
) -> tuple[pa.Table, pa.Table]:
    n = len(episodes)
    n_goals = np.array([len(i.goal_names) for i in infos], np.int64)
    goal_start = np.cumsum(n_goals) - n_goals
    total_goals = int(n_goals.sum())
    goals_completed = np.array([s.goals_completed for s in sims], np.int64)
    success = goals_completed == n_goals
    l_opt = np.array([i.l_opt for i in infos], np.int64)
    l_act = np.array([s.taken for s in sims], np.int64)
    longest = np.maximum(np.maximum(l_act, l_opt), 1)
    spl = np.where(success, np.where(l_opt > 0, l_opt / longest, 1.0), 0.0)

    # Per goal.
    steps_used = np.bincount(goal_slot, minlength=total_goals)
    switches = np.bincount(goal_slot, weights=switched, minlength=total_goals).astype(np.int64)
    completed_at = [c for s in sims for c in s.completed_at]
    started = [c for s in sims for c in s.started]
    dyn = [c for s in sims for c in s.dyn]
    done = np.array([c is not None for c in completed_at], np.bool_)
    dyn_value = np.array([-1 if d is None else d for d in dyn], np.int64)
    perfect = done & (dyn_value >= 0) & (steps_used <= dyn_value)
    goal_ep = np.repeat(np.arange(n), n_goals)

    n_switches = np.bincount(scored_ep, weights=switched, minlength=n).astype(np.int64)
    vsps_switches = np.bincount(goal_ep, weights=switches * done, minlength=n).astype(np.int64)
    vsps = vsps_switches / np.maximum(goals_completed, 1)
    visited_counts, visited_names, f1 = _visited(cache, infos, scored_ep, scored_rid)

    ids = pa.array([e.task.episode_id for e in episodes], pa.string())
    devices = pa.array([e.machine.device_id for e in episodes], pa.string())
    categories = pa.array([e.machine.category for e in episodes], pa.string())
    constant = [pa.array([v] * n, pa.string()) for v in head]
    episode_columns = [
        *constant, ids, devices, categories,
        pa.array(n_goals), pa.array(goals_completed), pa.array(success),
        pa.array([s.termination or "log_ended" for s in sims], pa.string()),
        pa.array(l_opt), pa.array(l_act), pa.array(spl), pa.array(f1),
        pa.array(n_switches), pa.array(vsps_switches),
        pa.array(vsps, mask=goals_completed == 0),
        pa.array(counts, pa.int64()), pa.array(np.array(counts) - l_act),
        pa.array(diverged, pa.int64()),
        pa.array([float(e.lam) for e in episodes], pa.float64()),
        pa.array([s.budget_global for s in sims], pa.float64()),
        pa.array([i.initial_state for i in infos], pa.string()),
        pa.array([e.setup.initial_view for e in episodes], pa.string()),
        pa.array([i.goal_names for i in infos], _STR_LIST),
        pa.array([i.c_opt for i in infos], _INT_LIST),
        pa.array([e.task.c_opt for e in episodes], _INT_LIST),
        ragged_strings(visited_counts, visited_names),
        pa.array([i.optimal_names for i in infos], _STR_LIST),
    ]  # fmt: skip
    schema = arrow_schema(EpisodeRow)
    episodes_table = pa.Table.from_arrays(episode_columns, schema=schema)

    take = pa.array(goal_ep)
    instructions = []
    for e, info in zip(episodes, infos, strict=True):
        given = e.task.instructions
        instructions += [given[g] if g < len(given) else None for g in range(len(info.goal_names))]
    goal_columns = [
        *(c.take(take) for c in (*constant, ids, devices, categories)),
        pa.array(np.repeat(n_goals, n_goals)),
        pa.array(np.arange(total_goals) - np.repeat(goal_start, n_goals)),
        pa.array([g for i in infos for g in i.goal_names], pa.string()),
        pa.array(instructions, pa.string()),
        pa.array([c for i in infos for c in i.c_opt], pa.int64()),
        pa.array(dyn, pa.int64()),
        pa.array([s is not None for s in started], pa.bool_()),
        pa.array(done),
        pa.array(started, pa.int64()),
        pa.array(completed_at, pa.int64()),
        pa.array(steps_used.astype(np.int64)),
        pa.array(switches),
        pa.array(perfect),
    ]
    goals_table = pa.Table.from_arrays(goal_columns, schema=arrow_schema(GoalRow))
    return episodes_table, goals_table


def _visited(
    cache: ColumnarCache, infos: list[SetupInfo], scored_ep: np.ndarray, scored_rid: np.ndarray
) -> tuple[np.ndarray, pa.Array, np.ndarray]:
    """Per episode: the visited states (reset states, then every state entered) in
    first-visit order, as (counts, names), and State-F1 against the optimal path."""
    n = len(infos)
    res = cache.results
    owner, row = ragged_rows(res["entered_start"][scored_rid], res["entered_count"][scored_rid])
    reset_counts = np.array([len(i.reset) for i in infos], np.int64)
    reset = np.array([s for i in infos for s in i.reset], np.int64)
    ep = np.concatenate([np.repeat(np.arange(n), reset_counts), scored_ep[owner]])
    state = np.concatenate([reset, cache.entered["state"][row]])
    # Within an episode the reset states come first, then the steps' states in order.
    order = np.lexsort((np.concatenate([np.zeros(len(reset)), np.ones(len(row))]), ep))
    key = ep[order] * len(cache.state_names) + state[order]
    _, first = np.unique(key, return_index=True)
    first.sort()
    visited_ep, visited = ep[order][first], state[order][first]
    counts = np.bincount(visited_ep, minlength=n)
    optimal_counts = np.array([len(i.optimal) for i in infos], np.int64)
    optimal = np.array([s for i in infos for s in i.optimal], np.int64)
    optimal_key = np.repeat(np.arange(n), optimal_counts) * len(cache.state_names) + optimal
    shared = np.bincount(
        visited_ep[np.isin(visited_ep * len(cache.state_names) + visited, optimal_key)],
        minlength=n,
    )
    f1 = 2.0 * shared / (counts + optimal_counts)
    return counts, cache.state_array.take(visited), f1
