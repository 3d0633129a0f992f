"""A batch of episodes through the compiled kernel, to Arrow tables."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pyarrow as pa

from ..semantics import (
    NO_PRICES,
    EpisodeLog,
    EpisodeResult,
    EpisodeRow,
    EpisodeSetup,
    GoalRow,
    Machine,
    Prices,
    Task,
    table_rows,
    table_tuples,
)
from ._assemble import tables
from ._engine import Vocab, replay_batch
from ._logline import LogLine

_PARAM_CACHE: dict[str, str] = {}
"""Raw parameter word -> normalised form, kept per process (bounded below)."""
_PARAM_CACHE_SIZE = 65_536


class EpisodeInput(NamedTuple):
    """One episode to replay: its machine, task, setup (the plan), log (decoded by msgspec,
    or straight into the kernel's structs) and lambda."""

    machine: Machine
    task: Task
    setup: EpisodeSetup
    log: EpisodeLog | LogLine
    lam: float


class BatchTables(NamedTuple):
    """The steps, episodes and goals tables of a batch, and rows per episode."""

    steps: pa.Table
    episodes: pa.Table
    goals: pa.Table
    step_counts: np.ndarray
    goal_counts: np.ndarray

    def episode_results(self, indices: list[int]) -> list[EpisodeResult]:
        """The rows of the batch's episodes `indices` as `replay_episode` returns them (the
        tables equal the reference's: tests/replay/kernel), for what reads rows rather than
        tables (the MCAP writer) without replaying the episodes again."""
        if not indices:
            return []
        step_at = np.concatenate(([0], np.cumsum(self.step_counts)))
        goal_at = np.concatenate(([0], np.cumsum(self.goal_counts)))
        steps = table_tuples(self.steps.take(_ranges(step_at, indices)))
        goals = table_rows(self.goals.take(_ranges(goal_at, indices)), GoalRow)
        episodes = table_rows(self.episodes.take(np.asarray(indices, np.int64)), EpisodeRow)
        results = []
        s = g = 0
        for j, episode in zip(indices, episodes, strict=True):
            n_steps, n_goals = int(self.step_counts[j]), int(self.goal_counts[j])
            results.append(EpisodeResult(steps[s : s + n_steps], episode, goals[g : g + n_goals]))
            s += n_steps
            g += n_goals
        return results


def _ranges(starts: np.ndarray, indices: list[int]) -> np.ndarray:
    """The row numbers of items `indices`, item j holding rows starts[j] to starts[j + 1]."""
    return np.concatenate([np.arange(starts[j], starts[j + 1]) for j in indices])


def replay_kernel(
    episodes: list[EpisodeInput],
    *,
    run_id: str,
    model: str,
    agent_kind: str,
    prices: Prices = NO_PRICES,
) -> BatchTables:
    """Replay a batch with the compiled kernel: the same tables as `replay_episode` of each
    episode followed by `rows_to_table`, built column by column (`prices`: the run's)."""
    if len(_PARAM_CACHE) > _PARAM_CACHE_SIZE:
        _PARAM_CACHE.clear()
    vocab = Vocab()
    out = replay_batch(episodes, vocab, _PARAM_CACHE)
    return BatchTables(*tables(out, vocab, episodes, (run_id, model, agent_kind), prices))
