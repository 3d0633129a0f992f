"""The observation and action spaces of `vge/Device-v0` (docs/LIVE.md lists the fields)."""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces

MAX_TEXT = 100_000
"""Longest text an observation field may hold (instructions, feedback)."""
MAX_ACTION_TEXT = 4_096
"""Length bound of the action space's samples (longer model texts are still accepted)."""
MAX_COUNT = 1 << 31
"""Bound of the step and goal counters."""


class AnyText(spaces.Text):
    """Any Unicode text up to `max_length` characters (instructions and feedback come from the
    benchmark, in any script). Samples draw from the base class's character set."""

    def contains(self, x: Any) -> bool:
        return isinstance(x, str) and self.min_length <= len(x) <= self.max_length


def observation_space(width: int, height: int) -> spaces.Dict:
    text = AnyText(MAX_TEXT, min_length=0)
    # A budget is above -1 after the step that exhausts it (PROTOCOL §3.5).
    budget = spaces.Box(-1.0, float(MAX_COUNT), shape=(), dtype=np.float64)
    return spaces.Dict(
        {
            "episode_id": text,
            "step": spaces.Discrete(MAX_COUNT),
            "image": spaces.Box(0, 255, shape=(height, width, 3), dtype=np.uint8),
            "view": text,
            "views": spaces.Sequence(text),
            "dashboard_unlocked": spaces.Discrete(2),
            "instruction": text,
            "goal_index": spaces.Discrete(MAX_COUNT),
            "n_goals": spaces.Discrete(MAX_COUNT),
            "feedback": text,
            "feedback_kind": text,
            "budget_global_left": budget,
            "budget_local_left": budget,
        }
    )


def action_space() -> spaces.Text:
    """The model's whole text (PROTOCOL §2). `step` also takes a structured action
    `{"type", "coord", "params"}`, which this space does not describe."""
    return AnyText(MAX_ACTION_TEXT, min_length=0)


__all__ = ["AnyText", "action_space", "observation_space"]
