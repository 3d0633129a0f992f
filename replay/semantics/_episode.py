"""Replay one logged episode: simulator + goals + budgets + classification -> rows.

`EpisodeSession` plays an episode one step at a time; `replay_episode`, the inner loop of
`vge replay`, is a loop over it, and so are the live tools. Pure: the same machine, task, log
and lambda always give the same rows.
"""

from __future__ import annotations

import datetime as _dt
from collections.abc import Sequence
from dataclasses import dataclass

import msgspec

from .._errors import TaskError
from ._budget import Budget, goals_reached
from ._classify import Classifier
from ._machine import Machine
from ._parse import ParsedAction, action_from_record, parse_action
from ._plan import Plan, c_opt_dynamic, plan_goals
from ._records import Continuation, EpisodeLog, LogStep, Task
from ._rows import CLASSIFICATION_FIELDS, EpisodeKey, EpisodeRow, GoalRow, StepRow
from ._step import Outcome, reset, step
from ._usage import NO_PRICES, Prices, origin_of, usage_cost
from ._vocab import DASHBOARD, FEEDBACK_KINDS, LOG_ENDED

_NO_ACTION = ParsedAction(False, None, "no_action", "", "")
_HITS_AT = CLASSIFICATION_FIELDS.index("hit_components")
_UNCLASSIFIED_HEAD = (None,) * _HITS_AT
_UNCLASSIFIED_TAIL = (None,) * (len(CLASSIFICATION_FIELDS) - _HITS_AT - 1)


@dataclass(frozen=True, slots=True)
class EpisodeSetup:
    """Everything about an episode that does not depend on the log (cacheable per task)."""

    goals: tuple[int, ...]
    initial_state: int
    reset_states: tuple[int, ...]
    start_state: int
    initial_view: str
    plan: Plan


def setup_episode(machine: Machine, task: Task) -> EpisodeSetup:
    """Resolve and check a task against its machine; raises TaskError with a clear message."""
    where = f"episode {task.episode_id!r}: "
    if not task.goals:
        raise TaskError(f"{where}no goals")
    index = machine.state_index
    goals = tuple(map(index.get, task.goals))
    if None in goals:
        unknown = [g for g in task.goals if g not in index]
        raise TaskError(f"{where}unknown goal state(s) {', '.join(map(repr, unknown))}")
    init_name = task.initial_state or machine.states[machine.initial]
    init = index.get(init_name)
    if init is None:
        raise TaskError(f"{where}unknown initial_state {init_name!r}")
    view = task.initial_view.lower()
    if view not in machine.views or view == DASHBOARD:
        offered = ", ".join(v for v in machine.views if v != DASHBOARD)
        raise TaskError(f"{where}initial_view {task.initial_view!r} is not one of: {offered}")
    sim, reset_states = reset(machine, init, view)
    plan = plan_goals(machine, sim.state, view, False, goals, where=where)
    return EpisodeSetup(goals, init, reset_states, sim.state, view, plan)


class EpisodeResult:
    """Rows of one replayed episode. Step rows are kept as tuples in `StepRow` field order
    (the fast path to Arrow); `steps` builds the typed rows on first use."""

    __slots__ = ("step_tuples", "episode", "goals", "_steps")

    def __init__(self, step_tuples: list[tuple], episode: EpisodeRow, goals: list[GoalRow]) -> None:
        self.step_tuples = step_tuples
        self.episode = episode
        self.goals = goals
        self._steps: list[StepRow] | None = None

    @property
    def steps(self) -> list[StepRow]:
        if self._steps is None:
            self._steps = [StepRow(*t) for t in self.step_tuples]
        return self._steps


def timestamp_seconds(value: float | str | None) -> float | None:
    """Recorded timestamp -> seconds since the epoch (ISO strings without zone are UTC)."""
    if value is None:
        return None
    if isinstance(value, (int, float)):
        return float(value)
    try:
        parsed = _dt.datetime.fromisoformat(value.strip().replace("Z", "+00:00"))
    except ValueError:
        return None
    if parsed.tzinfo is None:
        parsed = parsed.replace(tzinfo=_dt.UTC)
    return parsed.timestamp()


def parse_log_step(log_step: LogStep) -> ParsedAction:
    """The action of a log step: raw text is parsed, a structured action is checked."""
    if log_step.output is not None:
        return parse_action(log_step.output)
    if log_step.action is not None:
        a = log_step.action
        return action_from_record(a.type, a.coord, a.params)
    return _NO_ACTION


def advance_goals(
    entered: Sequence[int],
    goals: Sequence[int],
    current: int,
    k: int,
    started: list[int | None],
    completed_at: list[int | None],
    dyn: list[int | None],
) -> int:
    """PROTOCOL §3 goal bookkeeping for step k (`goals_reached`): each goal reached in it
    completes at k (one that became current in this very step also starts there, with
    C_opt_dyn 0), and the next goal starts at k + 1. Returns the new current goal index."""
    first = current
    current = goals_reached(entered, goals, first)
    for c in range(first, current):
        completed_at[c] = k
        if c != first:
            started[c] = k  # became current and completed in this step
            dyn[c] = 0
    if first < current < len(goals):
        started[current] = k + 1
    return current


def _action_fields(parsed: ParsedAction) -> tuple[str | None, float | None, float | None, list]:
    """(action_type, x, y, params) of a step's row: null and empty when nothing parsed."""
    action = parsed.action
    if action is None:
        return None, None, None, []
    coord = action.coord
    x, y = coord if coord is not None else (None, None)
    return action.type, x, y, list(action.params)


def _divergence(
    log_step: LogStep, outcome: Outcome, state_after: str, view_after: str
) -> tuple[bool | None, list[str]]:
    """Whether the values the log recorded differ from the replay's (null when it recorded
    none), and which (PROTOCOL §7.2: a recorded feedback kind is compared with the kind, a
    text with the text)."""
    feedback, state, view = log_step.feedback, log_step.state, log_step.view
    if feedback is None and state is None and view is None:
        return None, []
    fields = []
    if feedback is not None:
        mine = outcome.kind if feedback in FEEDBACK_KINDS else outcome.text
        if feedback != mine:
            fields.append("feedback")
    if state is not None and state != state_after:
        fields.append("state")
    if view is not None and view.lower() != view_after:
        fields.append("view")
    return bool(fields), fields


def _first_visit_order(states: list[int]) -> list[int]:
    seen: dict[int, None] = {}
    for s in states:
        seen.setdefault(s, None)
    return list(seen)


class EpisodeSession:
    """One episode played step by step (PROTOCOL §3-5): the simulator, goals, budgets and
    classification of `replay_episode`, one logged step at a time.

    `replay_episode` is a loop over it, and the live tools (the Gymnasium environment, the
    agent harness) drive the same object, so a live run and its replay cannot disagree.
    Pure like the step function: no clock, no randomness, no I/O.

    Read (never written from outside): `sim` (state, view, dashboard), `current` (the
    current goal's index; `n_goals` once all are completed), `goals` (state indices),
    `taken` (scored steps), `budget_local`, `budget_global_left`, `termination` (None while
    the episode runs), `rows` (the step rows so far), `instruction`, `done`.

    `prices` turn the tokens a step recorded into its cost; `continuation` (an episode of a
    continuation run, PROTOCOL §10.4) gives its steps their origin (PROTOCOL §7.2).
    """

    __slots__ = (
        "machine", "task", "setup", "budget", "c_opt", "goals", "n_goals", "sim", "visited",
        "current", "termination", "n_switches", "diverged_steps", "truncated_steps", "rows",
        "_head", "_classify", "_has_dashboard", "_started", "_completed_at", "_steps_used",
        "_switches", "_dyn", "prices", "continuation", "_prefix", "_fixed", "_prompt",
        "_completion", "_latency",
    )  # fmt: skip

    def __init__(
        self,
        machine: Machine,
        task: Task,
        *,
        lam: float,
        run_id: str,
        model: str,
        agent_kind: str,
        setup: EpisodeSetup | None = None,
        prices: Prices = NO_PRICES,
        continuation: Continuation | None = None,
    ) -> None:
        if setup is None:
            setup = setup_episode(machine, task)
        self.prices = prices
        self.continuation = continuation
        self._prefix = continuation.prefix_steps if continuation is not None else 0
        self._fixed = continuation is not None and continuation.fixed
        # Sums over the steps that recorded them; None while none has (PROTOCOL §7.3).
        self._prompt: int | None = None
        self._completion: int | None = None
        self._latency: float | None = None
        self.machine = machine
        self.task = task
        self.setup = setup
        self.goals = setup.goals
        self.n_goals = n_goals = len(setup.goals)
        self.c_opt = c_opt = setup.plan.c_opt
        self.budget = Budget(c_opt, lam)
        self.sim = sim = reset(machine, setup.initial_state, setup.initial_view)[0]
        self.visited: list[int] = list(setup.reset_states)
        self._classify = Classifier(machine).classify
        self._has_dashboard = bool(machine.dashboard_regions)
        # Per-goal bookkeeping.
        self._started: list[int | None] = [None] * n_goals
        self._completed_at: list[int | None] = [None] * n_goals
        self._steps_used = [0] * n_goals
        self._switches = [0] * n_goals
        self._dyn: list[int | None] = [None] * n_goals
        self._started[0] = 0
        self._dyn[0] = c_opt_dynamic(machine, sim.state, sim.view, sim.unlocked, setup.goals[0])
        self.current = 0
        self.termination: str | None = None
        self.n_switches = 0
        self.diverged_steps = 0
        self.truncated_steps = 0
        self.rows: list[tuple] = []
        self._head = (
            run_id,
            model,
            agent_kind,
            task.episode_id,
            machine.device_id,
            machine.category,
        )

    # ------------------------------------------------------------------ live view

    @property
    def done(self) -> bool:
        """The episode has terminated (PROTOCOL §3.5); later steps are truncated."""
        return self.termination is not None

    @property
    def instruction(self) -> str:
        """The instruction of the current goal ("" once every goal is completed)."""
        instructions = self.task.instructions
        return instructions[self.current] if self.current < len(instructions) else ""

    # ------------------------------------------------------------------ one step

    def advance(self, log_step: LogStep) -> tuple:
        """Play one logged step; returns its row (a tuple in `StepRow` field order)."""
        machine = self.machine
        names = machine.states
        k = len(self.rows)
        parsed = parse_log_step(log_step)
        action_type, x, y, params = _action_fields(parsed)
        ts = log_step.timestamp
        if ts is not None:
            ts = timestamp_seconds(ts)
        usage = self._usage(log_step, k)
        if self.termination is not None:
            self.truncated_steps += 1
            # Field order: StepRow (see _rows.py); nothing after termination is scored.
            row = (
                *self._head, k, None, None, None, None, None, action_type, parsed.action_text,
                parsed.thinking or None, log_step.output, x, y, params, parsed.ok,
                parsed.detail, None, None, None, None, [], None, None, None, None,
                *_UNCLASSIFIED_HEAD, [], *_UNCLASSIFIED_TAIL,
                None, None, True, log_step.feedback, log_step.state, log_step.view, None, [], ts,
                *usage,
            )  # fmt: skip
            self.rows.append(row)
            return row

        before = self.sim
        goal_index = self.current
        goal = self.goals[goal_index]
        sim, outcome = step(machine, before, parsed)
        self.sim = sim
        completed = self._advance_goals(k, goal_index, outcome)
        cls = self._classify(goal_index, goal, before, parsed, outcome, sim, completed)
        budget = self.budget
        self.termination = budget.termination
        diverged, diverged_fields = _divergence(log_step, outcome, names[sim.state], sim.view)
        if diverged:
            self.diverged_steps += 1

        tr = outcome.transition
        # Field order: StepRow (see _rows.py); `cls` is the CLASSIFICATION_FIELDS block.
        row = (
            *self._head, k, goal_index, names[goal], before.view, sim.view,
            sim.unlocked if self._has_dashboard else None, action_type, parsed.action_text,
            parsed.thinking or None, log_step.output, x, y, params, parsed.ok, parsed.detail,
            outcome.kind, outcome.text, names[before.state], names[sim.state],
            [names[s] for s in outcome.entered], tr.component if tr is not None else None,
            outcome.dangerous, outcome.switched, completed,
            *cls,
            budget.global_left, budget.local, False,
            log_step.feedback, log_step.state, log_step.view, diverged, diverged_fields, ts,
            *usage,
        )  # fmt: skip
        self.rows.append(row)
        return row

    def _advance_goals(self, k: int, goal_index: int, outcome: Outcome) -> int:
        """What step k did to the goals, the budgets and the tallies; returns the goals it
        completed."""
        machine, goals, sim = self.machine, self.goals, self.sim
        self.visited.extend(outcome.entered)
        current = advance_goals(
            outcome.entered, goals, goal_index, k, self._started, self._completed_at, self._dyn
        )
        self.current = current
        completed = current - goal_index
        self._steps_used[goal_index] += 1
        if outcome.switched:
            self.n_switches += 1
            self._switches[goal_index] += 1
        self.budget.spend(goal_index, current)
        if completed and current < self.n_goals:
            self._dyn[current] = c_opt_dynamic(
                machine, sim.state, sim.view, sim.unlocked, goals[current]
            )
        return completed

    def _usage(self, log_step: LogStep, k: int) -> tuple:
        """The last columns of step k's row (tokens, latency, cost, origin), added to the
        episode's sums. Truncated steps count: their tokens were paid for."""
        prompt = log_step.prompt_tokens
        completion = log_step.completion_tokens
        latency = log_step.latency_seconds
        if prompt is not None:
            self._prompt = prompt if self._prompt is None else self._prompt + prompt
        if completion is not None:
            self._completion = (
                completion if self._completion is None else self._completion + completion
            )
        if latency is not None:
            self._latency = latency if self._latency is None else self._latency + latency
        return (
            prompt,
            completion,
            latency,
            usage_cost(prompt, completion, self.prices),
            origin_of(k, self._prefix, self._fixed),
        )

    # ------------------------------------------------------------------ the end

    def finish(self, ended: str | None = None) -> EpisodeResult:
        """The step, episode and goal rows. An episode not terminated by its steps ends as
        `ended` says (the log's `ended`, PROTOCOL §1.4), else as `log_ended`."""
        if self.termination is None:
            self.termination = ended or LOG_ENDED
        names = self.machine.states
        setup, task, goals, n_goals, c_opt = (
            self.setup, self.task, self.goals, self.n_goals, self.c_opt
        )
        # The per-goal tallies, indexed by goal.
        started, completed_at, dyn, steps_used, switches = (
            self._started, self._completed_at, self._dyn, self._steps_used, self._switches
        )
        goals_completed = self.current
        success = goals_completed == n_goals
        l_opt = sum(c_opt)
        l_act = self.budget.taken
        spl = (l_opt / max(l_act, l_opt) if l_opt else 1.0) if success else 0.0
        visited_set = set(self.visited)
        optimal_list = list(setup.reset_states) + list(setup.plan.states)
        optimal_set = set(optimal_list)
        state_f1 = 2.0 * len(visited_set & optimal_set) / (len(visited_set) + len(optimal_set))
        vsps_switches = sum(switches[g] for g in range(n_goals) if completed_at[g] is not None)
        vsps = vsps_switches / goals_completed if goals_completed else None

        common = dict(zip(EpisodeKey.__struct_fields__, self._head, strict=True))
        episode = EpisodeRow(
            **common,
            n_goals=n_goals,
            goals_completed=goals_completed,
            success=success,
            termination=self.termination,
            L_opt=l_opt,
            L_act=l_act,
            spl=spl,
            state_f1=state_f1,
            n_switches=self.n_switches,
            vsps_switches=vsps_switches,
            vsps=vsps,
            n_steps=len(self.rows),
            truncated_steps=self.truncated_steps,
            diverged_steps=self.diverged_steps,
            lam=self.budget.lam,
            budget_global=self.budget.budget_global,
            initial_state=names[setup.initial_state],
            initial_view=setup.initial_view,
            goals=[names[g] for g in goals],
            c_opt=list(c_opt),
            c_opt_stated=list(task.c_opt) if task.c_opt is not None else None,
            visited_states=[names[s] for s in _first_visit_order(self.visited)],
            optimal_states=[names[s] for s in _first_visit_order(optimal_list)],
            prompt_tokens=self._prompt,
            completion_tokens=self._completion,
            latency_s=self._latency,
            cost_usd=usage_cost(self._prompt, self._completion, self.prices),
            **_continuation_columns(self.continuation),
        )
        instructions = task.instructions
        goal_rows = [
            GoalRow(
                **common,
                n_goals=n_goals,
                goal_index=g,
                goal_state=names[goals[g]],
                instruction=instructions[g] if g < len(instructions) else None,
                c_opt=c_opt[g],
                c_opt_dyn=dyn[g],
                reached=started[g] is not None,
                completed=completed_at[g] is not None,
                started_step=started[g],
                completed_step=completed_at[g],
                steps_used=steps_used[g],
                switches=switches[g],
                perfect=(
                    completed_at[g] is not None and dyn[g] is not None and steps_used[g] <= dyn[g]
                ),
            )
            for g in range(n_goals)
        ]
        return EpisodeResult(self.rows, episode, goal_rows)


def _continuation_columns(c: Continuation | None) -> dict:
    """The episode row's columns of the same names as `Continuation`'s fields (null without)."""
    if c is None:
        return dict.fromkeys(Continuation.__struct_fields__)
    return msgspec.structs.asdict(c)


def replay_episode(
    machine: Machine,
    task: Task,
    log: EpisodeLog,
    *,
    lam: float,
    run_id: str,
    model: str,
    agent_kind: str,
    setup: EpisodeSetup | None = None,
    prices: Prices = NO_PRICES,
) -> EpisodeResult:
    """Re-execute a logged episode (PROTOCOL §3-5) and return its step, episode and goal rows;
    `prices` (the run's, PROTOCOL §1.4) give the cost columns."""
    session = EpisodeSession(
        machine,
        task,
        lam=lam,
        run_id=run_id,
        model=model,
        agent_kind=agent_kind,
        setup=setup,
        prices=prices,
        continuation=log.continuation,
    )
    advance = session.advance
    for log_step in log.steps:
        advance(log_step)
    return session.finish(log.ended)
