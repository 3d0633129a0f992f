"""A batch of episodes through the compiled kernel, to Arrow tables."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pyarrow as pa

from ..semantics import NO_PRICES, EpisodeLog, EpisodeSetup, Machine, Prices, Task
from ._assemble import tables
from ._engine import Vocab, replay_batch

_PARAM_CACHE: dict[str, str] = {}
"""Raw parameter word -> normalised form, kept per process (bounded below)."""
_PARAM_CACHE_SIZE = 65_536


class EpisodeInput(NamedTuple):
    """One episode to replay: its machine, task, setup (the plan), log and lambda."""

    machine: Machine
    task: Task
    setup: EpisodeSetup
    log: EpisodeLog
    lam: float


class BatchTables(NamedTuple):
    """The steps, episodes and goals tables of a batch, and rows per episode."""

    steps: pa.Table
    episodes: pa.Table
    goals: pa.Table
    step_counts: np.ndarray
    goal_counts: np.ndarray


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
