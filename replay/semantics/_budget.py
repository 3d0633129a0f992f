"""Which λ an episode plays under, and its two budgets step by step (PROTOCOL §3.5).

One statement of the rules for every player of an episode: the replay (`EpisodeSession`),
the live tools (which reach it through the session) and the synthetic agent, which plays
through the pure step function and keeps a `Budget` of its own.
"""

from __future__ import annotations

from collections.abc import Sequence

from ._records import Task
from ._vocab import BUDGET_GLOBAL, BUDGET_LOCAL, DEFAULT_LAMBDA, SUCCESS


def episode_lambda(
    task: Task, run_lambda: float | None, option: float | None = None
) -> float:
    """The λ of an episode, first match wins: the replay option (`--lambda`), the task's own
    `lambda`, the run's (run.json), `DEFAULT_LAMBDA` (PROTOCOL §3.5). A live run has no
    option, so its replay without `--lambda` uses the same λ it was played with."""
    return _first(option, task.lam, run_lambda)


def run_lambda(run_lambda: float | None, option: float | None = None) -> float:
    """The λ of a run as a whole (the runs table's `lambda`, a live run's run.json): the
    option, else run.json's, else `DEFAULT_LAMBDA`; a task's own λ still wins per episode."""
    return _first(option, run_lambda)


def _first(*values: float | None) -> float:
    for value in values:
        if value is not None:
            return float(value)
    return DEFAULT_LAMBDA


def goals_reached(entered: Sequence[int], goals: Sequence[int], current: int) -> int:
    """PROTOCOL §3.4: the current goal's index after a step that entered `entered` (in order),
    from `current` before it. Each goal reached in turn completes, and the next one becomes
    current: one step may complete several."""
    n_goals = len(goals)
    for s in entered:
        if current < n_goals and s == goals[current]:
            current += 1
    return current


def refreshed_budget(
    budget_local: float, lam: float, c_opt: Sequence[int], first: int, current: int
) -> float:
    """B_local after goals `first` .. `current - 1` completed in one step (PROTOCOL §3.5): at
    least lam * C_opt of every goal that became current in it, the new current one included."""
    for c in range(first + 1, min(current + 1, len(c_opt))):
        budget_local = max(budget_local, lam * c_opt[c])
    return budget_local


def termination_after(
    current: int, n_goals: int, taken: int, budget_global: float, budget_local: float
) -> str | None:
    """PROTOCOL §3.5: how the episode ends after a step, or None if it goes on. Success is
    checked first, then the global budget, then the local one."""
    if current >= n_goals:
        return SUCCESS
    if taken >= budget_global:
        return BUDGET_GLOBAL
    if budget_local <= 0:
        return BUDGET_LOCAL
    return None


class Budget:
    """The budgets of one episode (PROTOCOL §3.5): `B_global = λ · Σ C_opt`, `B_local`
    starting at `λ · C_opt(g_1)`, and the termination they and the goals give.

    `spend(first, current)` accounts one step that moved the current goal from `first` to
    `current`; `termination` is then None while the episode goes on."""

    __slots__ = ("lam", "c_opt", "n_goals", "budget_global", "local", "taken", "termination")

    def __init__(self, c_opt: Sequence[int], lam: float) -> None:
        self.lam = lam = float(lam)
        self.c_opt = tuple(c_opt)
        self.n_goals = len(self.c_opt)
        self.budget_global = lam * sum(self.c_opt)
        self.local = lam * self.c_opt[0]
        self.taken = 0
        self.termination: str | None = None

    @property
    def global_left(self) -> float:
        """`B_global` minus the steps taken."""
        return self.budget_global - self.taken

    def spend(self, first: int, current: int) -> None:
        """One step, paid from the budget of the goal current before it (`first`); the goals
        it completed (`first` .. `current - 1`) refill the local budget afterwards."""
        self.taken += 1
        local = self.local - 1
        if current != first:
            local = refreshed_budget(local, self.lam, self.c_opt, first, current)
        self.local = local
        self.termination = termination_after(
            current, self.n_goals, self.taken, self.budget_global, local
        )
