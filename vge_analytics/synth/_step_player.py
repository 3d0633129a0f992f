"""The simulated agent at play: one response at a time (`StepPlayer`, driven by `vge run`'s
harness or by `play_episode`), in the form its log carries (text or a structured action),
and the time it takes (the synthetic timestamps)."""

from __future__ import annotations

import random

import replay
from replay.semantics import LEFT, RIGHT, SWITCH_VIEW, TOP

from ._agent import Agent, AgentStep, Decision
from ._catalog import Catalog
from ._profiles import Profile
from ._tasks import TaskRecord
from ._thinking import SLIP_KINDS, action_text, slip_text


class StepPlayer:
    """The agent of a profile, one response at a time, inside a loop that owns the device and
    the budgets (`play_episode` here, the harness of `vge run` elsewhere): `act` decides and
    formats, `observe` takes in what the step did."""

    def __init__(self, agent: Agent) -> None:
        self.agent = agent
        self.profile = agent.p
        self.rng = agent.rng
        self._pending: tuple[Decision, replay.ParsedAction, int, int] | None = None

    def act(
        self, sim: replay.SimState, goal_index: int, goal: int
    ) -> tuple[str | None, dict | None, replay.ParsedAction, Decision]:
        """The logged form of the next response: text (`output`) or a structured `record`."""
        decision = self.agent.decide(sim, goal_index, goal)
        output, record, parsed = _format(decision, self.profile, self.rng)
        self._pending = (decision, parsed, goal_index, goal)
        return output, record, parsed, decision

    def observe(
        self,
        before: replay.SimState,
        after: replay.SimState,
        outcome: replay.Outcome,
        completed: int,
    ) -> None:
        """What the last response did (the device before and after it, its outcome)."""
        assert self._pending is not None, "observe() follows act()"
        decision, parsed, goal_index, goal = self._pending
        self._pending = None
        self.agent.observe(decision, parsed, before, after, outcome, goal_index, goal, completed)


def play_episode(
    machine: replay.Machine,
    catalog: Catalog,
    profile: Profile,
    task: TaskRecord,
    rng: random.Random,
    run_lambda: float | None = None,
) -> list[AgentStep]:
    """Run the agent until the episode terminates (success or a budget), under the λ its
    replay will use (`replay.episode_lambda`) and the replay's own budget rules
    (`replay.Budget`), so the replay of the log ends exactly at its last step."""
    plain = task.to_task()
    setup = replay.semantics.setup_episode(machine, plain)
    sim, _ = replay.reset(machine, setup.initial_state, setup.initial_view)
    budget = replay.Budget(setup.plan.c_opt, replay.episode_lambda(plain, run_lambda))
    player = StepPlayer(Agent(machine, catalog, profile, task, rng))
    steps: list[AgentStep] = []
    goal_index = 0
    while budget.termination is None:
        output, record, parsed, decision = player.act(sim, goal_index, setup.goals[goal_index])
        before = sim
        sim, outcome = replay.step(machine, sim, parsed)
        current = replay.goals_reached(outcome.entered, setup.goals, goal_index)
        budget.spend(goal_index, current)
        player.observe(before, sim, outcome, current - goal_index)
        goal_index = current
        steps.append(
            AgentStep(decision, output, record, outcome, sim.view, machine.states[sim.state])
        )
    return steps


def _format(
    decision: Decision, profile: Profile, rng: random.Random
) -> tuple[str | None, dict | None, replay.ParsedAction]:
    """The logged form of a decision and what the engine will parse from it."""
    action = decision.action
    if profile.agent_kind == "human":
        record = {
            "type": replay.DISPLAY_NAMES[action.type],
            "coord": [round(action.coord[0]), round(action.coord[1])] if action.coord else None,
            "params": list(action.params),
        }
        parsed = replay.semantics.action_from_record(record["type"], record["coord"], record["params"])
        return None, record, parsed
    if rng.random() < profile.slip:
        kind = rng.choice(SLIP_KINDS)
        alternative = replay.Action(SWITCH_VIEW, None, (rng.choice((LEFT, RIGHT, TOP)),))
        text = slip_text(kind, decision.thinking, action, alternative)
    else:
        text = f"Thinking: {decision.thinking}\n{action_text(action, rng, profile.decorated)}"
    return text, None, replay.parse_action(text)


def think_seconds(profile: Profile, rng: random.Random) -> float:
    """Seconds the agent takes for one step (for the synthetic timestamps)."""
    mean, spread = profile.seconds
    return max(0.8, rng.gauss(mean, spread))
