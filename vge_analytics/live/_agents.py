"""What `vge run` needs of an agent.

An agent gives, per episode, a *player*: `act(obs) -> Reply` answers one observation of
`vge/Device-v0`; `observe(obs, info)` hears what the step did (the next observation and the
step's row). `check()` runs once, before the first episode. The three kinds:
`module:callable` (`_module.py`), `sim:PROFILE` (`_sim.py`) and `openai:MODEL` (`_vlm.py`);
`load_agent` (`_agent_spec.py`) reads the AGENT argument.
"""

from __future__ import annotations

import threading
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Protocol

import msgspec

from replay.env import DeviceEnv

from ._openai import ClientSettings

AGENT_KINDS = ("vlm", "human", "scripted")


@dataclass(frozen=True, slots=True)
class Reply:
    """One response, as the log will carry it (PROTOCOL §1.4)."""

    action: str | Mapping[str, Any]
    """The model's whole text, or a structured action `{"type", "coord", "params"}`."""
    prompt_tokens: int | None = None
    completion_tokens: int | None = None
    latency_seconds: float | None = None
    timestamp: float | None = None
    """Only agents that measure time set these (a deterministic agent's log has no clock)."""


@dataclass(frozen=True, slots=True)
class EpisodeStart:
    """What an agent gets when an episode starts."""

    obs: dict[str, Any]
    """The first observation."""
    env: DeviceEnv
    """The environment, for agents that play from privileged knowledge (`sim:`) only."""
    run_id: str
    stop: threading.Event | None = None
    """Set when the run is stopping: an agent waiting to retry a request stops waiting."""


class Player(Protocol):
    """One episode of an agent. A player may also have `recall(obs, step, after, info)`:
    in a continuation run (PROTOCOL §10.4), each step before the cut (a `replay.LogStep`)
    with the observations before and after it, for an agent that keeps a history."""

    def act(self, obs: dict[str, Any]) -> Reply: ...

    def observe(self, obs: dict[str, Any], info: dict[str, Any]) -> None: ...


class LiveAgent(Protocol):
    """An agent `vge run` can run."""

    spec: str
    """AGENT as given (`module:callable`, `sim:PROFILE`, `openai:MODEL`)."""
    agent_kind: str
    """run.json's agent kind."""
    model: str
    """run.json's model, unless `--model` says otherwise."""
    looks: bool
    """Whether it reads the image (if not, views are not rendered)."""

    def settings(self) -> dict[str, Any]:
        """What decides its behaviour, for run.json's meta (compared on `--resume`)."""
        ...

    def check(self) -> None:
        """Called once before the first episode, before anything is written: raises when
        the agent cannot play at all (a model server it cannot reach, that refuses its key
        or does not know its model)."""
        ...

    def start(self, episode: EpisodeStart) -> Player: ...


class AgentOptions(msgspec.Struct, frozen=True):
    """The options of `vge run` that agents read."""

    history: int | None = None
    """Steps of history the agent keeps (None: the whole episode)."""
    history_images: int | None = None
    """Of the steps kept, how many of the latest keep their picture (None: all of them)."""
    seed: int = 0
    """Seed of the simulated profiles."""
    client: ClientSettings = ClientSettings()
    """How `openai:` agents reach their model."""


def history_text(history: int | None) -> str:
    return "unlimited" if history is None else str(history)


__all__ = [
    "AGENT_KINDS",
    "AgentOptions",
    "EpisodeStart",
    "LiveAgent",
    "Player",
    "Reply",
    "history_text",
]
