"""The observation and action spaces of `vge/Device-v0` (docs/LIVE.md lists the fields).

Every space is bounded by the benchmark (`BenchBounds`) or the vocabulary, and every one can
be laid out in shared memory (`_textspaces`), so an async vector env works with its defaults.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from gymnasium import spaces

from ..semantics import FEEDBACK_KINDS, VIEW_ORDER
from ._textspaces import AnyText, ViewNames

if TYPE_CHECKING:  # the spaces read the bounds; computing them is `_bounds`'s job
    from ._bounds import BenchBounds

MAX_FEEDBACK = 100_000
"""Longest feedback text (it quotes the SSM's descriptions, which are free text)."""
MAX_ACTION_TEXT = 4_096
"""Length bound of the action space's samples (longer model texts are still accepted)."""


def budget_space(
    bounds: BenchBounds, shape: tuple[int, ...], dtype: type[np.floating]
) -> spaces.Box:
    """Budgets left: each at most the largest `B_global`, and above -1 after the step that
    exhausts it (PROTOCOL §3.5)."""
    return spaces.Box(-1.0, bounds.budget, shape=shape, dtype=dtype)


def observation_space(width: int, height: int, bounds: BenchBounds) -> spaces.Dict:
    budget = budget_space(bounds, (), np.float64)
    return spaces.Dict(
        {
            "episode_id": AnyText(bounds.episode_id, min_length=0),
            "step": spaces.Discrete(bounds.steps + 1),
            "image": spaces.Box(0, 255, shape=(height, width, 3), dtype=np.uint8),
            "view": AnyText(max(map(len, VIEW_ORDER)), min_length=0),
            "views": ViewNames(),
            "dashboard_unlocked": spaces.Discrete(2),
            "instruction": AnyText(bounds.instruction, min_length=0),
            "goal_index": spaces.Discrete(bounds.goals + 1),
            "n_goals": spaces.Discrete(bounds.goals, start=1),
            "feedback": AnyText(MAX_FEEDBACK, min_length=0),
            "feedback_kind": AnyText(max(map(len, FEEDBACK_KINDS)), min_length=0),
            "budget_global_left": budget,
            "budget_local_left": budget,
        }
    )


def action_space() -> spaces.Text:
    """The model's whole text (PROTOCOL §2). `step` also takes a structured action
    `{"type", "coord", "params"}`, which this space does not describe."""
    return AnyText(MAX_ACTION_TEXT, min_length=0)


__all__ = ["AnyText", "action_space", "budget_space", "observation_space"]
