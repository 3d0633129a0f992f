"""The largest values an episode of a benchmark can show: what bounds the environments' spaces.

Gymnasium's spaces need finite bounds, and tight ones: `FlattenObservation` turns a
`Discrete(n)` into an n-long one-hot, so a counter bounded by 2**31 cost 2 GiB per
observation. The bounds are taken over every playable task of the benchmark, since a reset
may play any of them (`options={"episode_id": ...}`), under the λ the environment plays with.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .._errors import ConfigError, VGEError
from ..io import Benchmark
from ..semantics import Budget, episode_lambda, setup_episode


@dataclass(frozen=True, slots=True)
class BenchBounds:
    """Maxima over the playable tasks of a benchmark (PROTOCOL §3.5 for the budgets)."""

    budget: float
    """The largest `B_global = λ · L_opt`; `B_local` never exceeds its episode's `B_global`
    (it is `λ · C_opt` of one goal)."""
    steps: int
    """The most steps an episode can take: it ends once the steps taken reach `B_global`
    (one at least: the first step is always taken, even with λ = 0)."""
    goals: int
    """The most goals of a task."""
    episode_id: int
    """The longest episode id, in characters."""
    instruction: int
    """The longest instruction, in characters."""


def bench_bounds(bench: Benchmark, lam: float | None) -> BenchBounds:
    """The bounds of `bench` played with the run's λ `lam` (a task's own λ wins). Tasks that
    cannot be played are passed over, as a reset passes over them."""
    budget = 0.0
    goals = 0
    ids = 0
    instructions = 0
    problem: str | None = None
    for episode_id, entry in bench.tasks.items():
        task = entry.task
        try:
            setup = setup_episode(bench.machine(task.device_id), task)
        except VGEError as exc:
            problem = problem or str(exc)
            continue
        # The session's own budget object, so the bound is the very float it compares with.
        budget = max(budget, Budget(setup.plan.c_opt, episode_lambda(task, lam)).budget_global)
        goals = max(goals, len(setup.goals))
        ids = max(ids, len(episode_id))
        instructions = max(instructions, max(map(len, task.instructions), default=0))
    if goals == 0:
        raise ConfigError(
            f"{bench.tasks_path}: no playable episode"
            + (f" (first problem: {problem})" if problem else "")
        )
    return BenchBounds(budget, max(1, math.ceil(budget)), goals, ids, instructions)


__all__ = ["BenchBounds", "bench_bounds"]
