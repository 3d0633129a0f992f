"""`vge/DeviceRL-v0`: `vge/Device-v0` with spaces that reinforcement-learning code can use.

The same environment, the same `EpisodeSession`: `step` turns the `MultiDiscrete` action into
the structured action `vge/Device-v0` takes (`_actions`) and steps it, so the reward,
termination, truncation and `info` are that environment's. Only the spaces differ: the
observation is a `Dict` of `Box`es (no text), which `FlattenObservation` turns into one
vector, and every sampled action is a well-formed action.
"""

from __future__ import annotations

from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from gymnasium import spaces

from .._errors import ConfigError
from ..io import Benchmark
from ..semantics import VIEW_ORDER, VIEW_RANK
from ._actions import DEFAULT_GRID, rl_action_space, structured_action
from ._env import DeviceEnv
from ._spaces import budget_space

if TYPE_CHECKING:
    from ._bounds import BenchBounds

RL_IMAGE_SIZE = 128
"""Default width and height of the RL observation's image (flattened: 128 · 128 · 3 values)."""


def rl_observation_space(width: int, height: int, bounds: BenchBounds) -> spaces.Dict:
    """Keys in `FlattenObservation`'s order (a `Dict` sorts them): budgets, dashboard_unlocked,
    goal, image, view."""
    unit = {"low": 0.0, "high": 1.0, "dtype": np.float32}  # flags and one-hots
    return spaces.Dict(
        {
            "budgets": budget_space(bounds, (2,), np.float32),  # global left, local left
            "dashboard_unlocked": spaces.Box(shape=(1,), **unit),
            "goal": spaces.Box(shape=(bounds.goals + 1,), **unit),
            "image": spaces.Box(0, 255, shape=(height, width, 3), dtype=np.uint8),
            "view": spaces.Box(shape=(len(VIEW_ORDER),), **unit),
        }
    )


class DeviceRLEnv(DeviceEnv):
    """A device of a VGEBench-style benchmark for RL code: `MultiDiscrete` actions on a grid of
    the views, `Box` observations (docs/LIVE.md).

    Takes the options of `DeviceEnv`, with images of `RL_IMAGE_SIZE` by default, and `grid`,
    the cells per axis of the action grid.
    """

    def __init__(
        self,
        bench: str | Path | Benchmark,
        *,
        grid: int = DEFAULT_GRID,
        image_width: int = RL_IMAGE_SIZE,
        image_height: int = RL_IMAGE_SIZE,
        **options: Any,
    ) -> None:
        super().__init__(bench, image_width=image_width, image_height=image_height, **options)
        if grid < 1:
            raise ConfigError(f"grid must be at least 1 cell per axis, not {grid}")
        self.grid = grid
        self.action_space = rl_action_space(grid)  # type: ignore[assignment]

    @cached_property
    def observation_space(self) -> spaces.Dict:  # type: ignore[override]
        return rl_observation_space(*self.image_size, self.bounds)

    def structured_action(self, action: Any) -> dict[str, Any]:
        """The structured action `{"type", "coord", "params"}` that `step(action)` plays (what a
        log of the episode holds: `replay.env.log_step_of(env.structured_action(a))`)."""
        return structured_action(action, self.grid)

    def step(  # type: ignore[override]
        self, action: Any
    ) -> tuple[dict[str, Any], float, bool, bool, dict[str, Any]]:
        """One action `[type, x cell, y cell, parameter choice]`."""
        return super().step(self.structured_action(action))

    def _observation(self) -> dict[str, Any]:
        session = self.session
        assert session is not None
        view = np.zeros(len(VIEW_ORDER), dtype=np.float32)
        view[VIEW_RANK[session.sim.view]] = 1.0
        goal = np.zeros(self.bounds.goals + 1, dtype=np.float32)
        goal[session.current] = 1.0
        return {
            "budgets": np.array(
                [session.budget.global_left, session.budget.local], dtype=np.float32
            ),
            "dashboard_unlocked": np.array([self._dashboard_unlocked()], dtype=np.float32),
            "goal": goal,
            "image": self._image(),
            "view": view,
        }


__all__ = ["RL_IMAGE_SIZE", "DeviceRLEnv", "rl_observation_space"]
