"""`sim:PROFILE`: the simulated profiles of `vge synth` as agents of `vge run`.

A profile decides from privileged knowledge of the device (which transitions make progress),
so its player reads the episode the environment plays rather than the observation. Its
random choices come from a generator seeded by (seed, run id, episode id), as in `vge synth`:
a run is byte-identical however often it is played or resumed, and with the same run id and
seed it makes the same choices as the synthetic run of that profile.
"""

from __future__ import annotations

from typing import Any

import replay

from .._errors import AgentError
from ..synth import (
    PROFILES,
    Agent,
    Catalog,
    Profile,
    StepPlayer,
    TaskRecord,
    agent_rng,
    is_known_category,
    load_catalog,
)
from ._agents import AgentOptions, EpisodeStart, Reply, history_text


def find_profile(name: str) -> Profile:
    """A profile by its name (`sim-vlm-f`) or the end of it (`vlm-f`, `f`, `human`)."""
    for p in PROFILES:
        if name == p.name or p.name.endswith(f"-{name}"):
            return p
    names = ", ".join(p.name for p in PROFILES)
    raise AgentError(f"agent sim:{name}: no such profile; the profiles are {names}")


def _catalog(category: str) -> Catalog:
    """The category's catalog; a device of another benchmark gets an empty one (the profile
    then guesses actions from no knowledge of the component kinds)."""
    if is_known_category(category):
        return load_catalog(category)
    return Catalog(category, "medium", "box", False, {}, {}, category.lower())


class SimAgent:
    looks = False

    def __init__(self, name: str, options: AgentOptions) -> None:
        profile = find_profile(name)
        if options.history is not None:
            profile = profile.with_history(options.history)
        self.profile = profile
        self.spec = f"sim:{profile.name}"
        self.model = profile.name
        self.agent_kind = profile.agent_kind
        self.seed = options.seed

    def settings(self) -> dict[str, Any]:
        p = self.profile
        return {
            "agent": self.spec,
            "simulated": True,
            "profile": p.name,
            "mimics": p.mimics,
            "history_length": history_text(p.history_length),
            "seed": self.seed,
        }

    def check(self) -> None:
        """Nothing to reach: the profile plays in this process."""

    def start(self, episode: EpisodeStart) -> _SimPlayer:
        session = episode.env.session
        assert session is not None
        task = session.task
        machine = session.machine
        record = TaskRecord(
            task.episode_id,
            task.device_id,
            tuple(task.goals),
            tuple(task.instructions),
            task.initial_view,
            tuple(task.c_opt or ()),
        )
        rng = agent_rng(self.seed, episode.run_id, task.episode_id)
        player = StepPlayer(Agent(machine, _catalog(machine.category), self.profile, record, rng))
        return _SimPlayer(player, session)


class _SimPlayer:
    def __init__(self, player: StepPlayer, session: replay.EpisodeSession) -> None:
        self.player = player
        self.session = session
        self._before: tuple[replay.SimState, replay.ParsedAction] | None = None

    def act(self, obs: dict[str, Any]) -> Reply:
        s = self.session
        output, record, parsed, _ = self.player.act(s.sim, s.current, s.goals[s.current])
        self._before = (s.sim, parsed)
        return Reply(output if output is not None else record)  # type: ignore[arg-type]

    def observe(self, obs: dict[str, Any], info: dict[str, Any]) -> None:
        assert self._before is not None
        before, parsed = self._before
        # The pure step again, for the outcome the profile learns from (the session keeps
        # only the row); it lands where the session is.
        after, outcome = replay.step(self.session.machine, before, parsed)
        assert after == self.session.sim
        self.player.observe(before, after, outcome, info["completed_goals"])


__all__ = ["SimAgent", "find_profile"]
