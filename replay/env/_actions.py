"""The action space of `vge/DeviceRL-v0`: four integers that always make a well-formed action.

`[type, x cell, y cell, parameter choice]`, a `MultiDiscrete([7, grid, grid, 9])`:

- `type` indexes `ACTION_TYPES` (PROTOCOL §2's seven actions, in the grammar's order);
- cells `(i, j)` of a `grid` x `grid` division of the view are its centres on the 0..1000
  scale, `x = (i + 1/2) · 1000 / grid`, `y = (j + 1/2) · 1000 / grid` (the default grid, 100,
  puts a point every 10 units, finer than the smallest box of the bundled benchmark, 16.3
  units high); interactions and `Switch_view` carry the point (a `Switch_view` to the locked
  dashboard is an active unlock when the point lies on the dashboard region, PROTOCOL §3.2),
  `Timed_wait` none;
- the parameter choice `k` picks entry `k mod n` of the type's `n` parameter lists in
  `PARAMETERS`, the action space of the paper's prompt (docs/LIVE.md has the table).

`structured_action` turns it into the structured action a human log carries
(`{"type", "coord", "params"}`), which `vge/Device-v0` also takes: both environments step
the same session with the same kind of action, so their step rows are alike.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces

from .._errors import ActionError
from ..semantics import (
    ACTION_NAMES,
    DISPLAY_NAMES,
    GRASP,
    GRASP_STATES,
    PRESS,
    PRESS_KINDS,
    PULL,
    PULL_DIRECTIONS,
    PUSH,
    PUSH_DIRECTIONS,
    ROTATE,
    ROTATE_DIRECTIONS,
    ROTATE_NOTCHES,
    SCALE,
    SWITCH_VIEW,
    TIMED_WAIT,
    VIEW_ORDER,
)

ACTION_TYPES: tuple[str, ...] = tuple(DISPLAY_NAMES[name] for name in ACTION_NAMES)
"""`Press, Rotate, Push, Pull, Grasp, Switch_view, Timed_wait`: the first integer."""


def _each(codes: tuple[str, ...]) -> tuple[tuple[int], ...]:
    """One list per code of a parameter (PROTOCOL §2's codes)."""
    return tuple((code,) for code in range(len(codes)))


PARAMETERS: dict[str, tuple[tuple[int | str, ...], ...]] = {
    DISPLAY_NAMES[PRESS]: _each(PRESS_KINDS),
    # direction and notches; a transition's `*` accepts any value, so no list needs one (an
    # agent's `*` would match only a `*`, §1.2).
    DISPLAY_NAMES[ROTATE]: tuple(
        (d, n) for d in range(len(ROTATE_DIRECTIONS)) for n in ROTATE_NOTCHES
    ),
    DISPLAY_NAMES[PUSH]: _each(PUSH_DIRECTIONS),
    DISPLAY_NAMES[PULL]: _each(PULL_DIRECTIONS),
    DISPLAY_NAMES[GRASP]: _each(GRASP_STATES),
    DISPLAY_NAMES[SWITCH_VIEW]: tuple((v,) for v in VIEW_ORDER),
    DISPLAY_NAMES[TIMED_WAIT]: ((),),
}
"""The parameter lists of each action type (the fourth integer picks one)."""

CHOICES = max(len(lists) for lists in PARAMETERS.values())
"""Values of the parameter choice: the longest list of `PARAMETERS` (9, the views)."""

DEFAULT_GRID = 100
_NO_POINT = frozenset({DISPLAY_NAMES[TIMED_WAIT]})


def rl_action_space(grid: int) -> spaces.MultiDiscrete:
    return spaces.MultiDiscrete(np.array([len(ACTION_TYPES), grid, grid, CHOICES], dtype=np.int64))


def cell_centre(index: int, grid: int) -> float:
    """The centre of cell `index` of `grid` on the 0..SCALE scale."""
    return (2 * index + 1) * SCALE / (2 * grid)


def structured_action(action: Any, grid: int) -> dict[str, Any]:
    """`[type, x cell, y cell, choice]` as `{"type", "coord", "params"}`; anything outside the
    space raises `replay.ActionError` in one line."""
    values = np.asarray(action)
    if values.shape != (4,) or not np.issubdtype(values.dtype, np.integer):
        raise ActionError(f"a DeviceRL action is 4 integers [type, x, y, choice], not {action!r}")
    kind, x, y, choice = (int(v) for v in values)
    highs = (len(ACTION_TYPES), grid, grid, CHOICES)
    if not all(0 <= v < high for v, high in zip((kind, x, y, choice), highs, strict=True)):
        raise ActionError(f"DeviceRL action {[kind, x, y, choice]} is outside {list(highs)}")
    name = ACTION_TYPES[kind]
    lists = PARAMETERS[name]
    coord = None if name in _NO_POINT else [cell_centre(x, grid), cell_centre(y, grid)]
    return {"type": name, "coord": coord, "params": list(lists[choice % len(lists)])}


__all__ = [
    "ACTION_TYPES",
    "CHOICES",
    "DEFAULT_GRID",
    "PARAMETERS",
    "cell_centre",
    "rl_action_space",
    "structured_action",
]
