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

Episodes this path does not cover (a machine with more rects, components or states than
its int masks and memo keys hold, a global budget of 2**52 steps or more, a non-finite
coordinate) are replayed by `replay_episode` and merged in order.
`tests/replay/test_columnar.py` checks the equality, table against table.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import pyarrow as pa

from ..semantics._episode import EpisodeSetup, replay_episode
from ..semantics._machine import Machine
from ..semantics._records import EpisodeLog, LogStep, Task
from ..semantics._rows import EpisodeRow, GoalRow, StepRow
from ..semantics._tables import rows_to_table
from . import _columnar_arrow as arw
from ._columnar_classify import Scored, classify
from ._columnar_episodes import episode_tables
from ._columnar_parse import ParsedSteps, parse_steps
from ._columnar_sim import (
    EXACT_BUDGET,
    EpisodeSim,
    scored_progress,
    simulate_episode,
    step_keys,
)
from ._columnar_steps import step_table
from ._columnar_tables import ColumnarCache, MachineTables, SetupInfo


class EpisodeInput(NamedTuple):
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
    infos = [cache.setup(e.setup, e.machine) for e in episodes]
    parsed = parse_steps(steps, cache.actions)
    head = (run_id, model, agent_kind)
    scalar = _needs_scalar(episodes, infos, counts, parsed)
    if not scalar:
        batch = _replay(cache, episodes, infos, steps, counts, parsed, head)
        batch.fast_parsed = parsed.fast
        return batch
    return _merge(cache, episodes, infos, steps, counts, parsed, head, scalar)


def _needs_scalar(
    episodes: list[EpisodeInput], infos: list[SetupInfo], counts: list[int], parsed: ParsedSteps
) -> list[int]:
    """Episodes for the scalar path: a machine too large for the int masks, a non-finite
    coordinate, or a budget too large to be decremented exactly in floats."""
    bad = parsed.has_coord & ~(np.isfinite(parsed.x) & np.isfinite(parsed.y))
    odd = set()
    if bad.any():
        odd = set(np.repeat(np.arange(len(counts)), counts)[bad].tolist())
    return [
        i
        for i, (e, info) in enumerate(zip(episodes, infos, strict=True))
        if i in odd or not info.mt.supported or not e.lam * info.l_opt < EXACT_BUDGET
    ]


def _merge(
    cache: ColumnarCache,
    episodes: list[EpisodeInput],
    infos: list[SetupInfo],
    steps: list[LogStep],
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
    fast = _replay(
        cache,
        [episodes[i] for i in keep],
        [infos[i] for i in keep],
        [steps[i] for i in rows.tolist()],
        [counts[i] for i in keep],
        sub,
        head,
    )
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
    infos: list[SetupInfo],
    steps: list[LogStep],
    counts: list[int],
    parsed: ParsedSteps,
    head: tuple[str, str, str],
) -> ColumnarBatch:
    n = len(steps)
    n_eps = len(episodes)
    mts: list[MachineTables] = []
    where: dict[int, int] = {}
    ep_machine = np.zeros(n_eps, np.int64)
    for e, info in enumerate(infos):
        j = where.get(info.mt.gid)
        if j is None:
            j = where[info.mt.gid] = len(mts)
            mts.append(info.mt)
            info.mt.check_size()
        ep_machine[e] = j
    step_ep = np.repeat(np.arange(n_eps), counts)

    # 2. The sequential loop: one result id per scored step.
    keys, points = step_keys(
        cache, mts, ep_machine[step_ep], parsed.aid, parsed.x, parsed.y, parsed.has_coord
    )
    aids, xs, ys = parsed.aid.tolist(), parsed.x.tolist(), parsed.y.tolist()
    has_coord = parsed.has_coord.tolist()
    rids: list[int] = []
    sims: list[EpisodeSim] = []
    begin = 0
    for e, info in enumerate(infos):
        end = begin + counts[e]
        sims.append(
            simulate_episode(
                cache,
                info.mt,
                info.setup,
                float(episodes[e].lam),
                keys,
                points,
                aids,
                xs,
                ys,
                has_coord,
                begin,
                end,
                rids,
            )  # fmt: skip
        )
        begin = end

    # The scored steps (the first `taken` of each episode) and their situation.
    taken = np.array([s.taken for s in sims], np.int64)
    step_k = np.arange(n) - (np.cumsum(counts) - counts).astype(np.int64)[step_ep]
    scored = np.flatnonzero(step_k < taken[step_ep])
    rid = np.array(rids, np.int64)
    res = cache.results
    s1, v1, unlocked, outcome = (res[c][rid] for c in ("state", "view", "unlocked", "outcome"))
    sep, k = step_ep[scored], step_k[scored]
    completed, goal_index, b_local = scored_progress(sims, sep, k, scored)
    first = k == 0
    start_state = np.array([i.start_state for i in infos], np.int64)
    start_view = np.array([i.start_view for i in infos], np.int64)
    goal_counts = [len(i.goals) for i in infos]
    goal_slot = (np.cumsum(goal_counts) - goal_counts).astype(np.int64)[sep] + goal_index
    sc = Scored(
        ep=sep,
        machine=ep_machine[sep],
        goal_index=goal_index,
        goal=np.array([g for i in infos for g in i.goals], np.int64)[goal_slot],
        dist_base=np.array([d for i in infos for d in i.dist_base], np.int64)[goal_slot],
        trect_base=np.array([t for i in infos for t in i.trect_base], np.int64)[goal_slot],
        s0=np.where(first, start_state[sep], np.roll(s1, 1)),
        s1=s1,
        v0=np.where(first, start_view[sep], np.roll(v1, 1)),
        v1=v1,
        outcome=outcome,
        completed=completed,
        aid=parsed.aid[scored],
        x=parsed.x[scored],
        y=parsed.y[scored],
        has_coord=parsed.has_coord[scored],
        point=np.array(points, np.int64)[scored],
    )

    # 3. Classification; 4. the tables.
    cl = classify(cache, mts, sc)
    budget_global = np.array([s.budget_global for s in sims])
    steps_table, diverged = step_table(
        cache, episodes, steps, parsed, step_ep, step_k, scored, sc, cl, head, unlocked,
        b_local, budget_global, mts,
    )  # fmt: skip
    switched = cache.outcomes.cols["switched"][outcome]
    episodes_table, goals_table = episode_tables(
        cache, infos, episodes, sims, counts, head, sep, rid, goal_slot, switched, diverged
    )
    return ColumnarBatch(steps_table, episodes_table, goals_table, counts, goal_counts)


__all__ = ["ColumnarBatch", "ColumnarCache", "EpisodeInput", "replay_columnar"]
