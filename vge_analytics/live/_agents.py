"""What `vge run` needs of an agent, and the `module:callable` kind.

An agent gives, per episode, a *player*: `act(obs) -> Reply` answers one observation of
`vge/Device-v0`; `observe(obs, info)` hears what the step did (the next observation and the
step's row). The three kinds: `module:callable` (here), `sim:PROFILE` (`_sim.py`) and
`openai:MODEL` (`_vlm.py`); `load_agent` reads the AGENT argument.
"""

from __future__ import annotations

import copy
import importlib
import os
import sys
import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol

import msgspec

from replay.env import DeviceEnv

from .._errors import AgentError
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


class Player(Protocol):
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


# ---------------------------------------------------------------------- module:callable


class ModuleAgent:
    """`module:callable`: `agent(obs) -> str` (the model's text) or a structured action;
    an object may also have `reset(obs)`, called when an episode starts.

    With `--concurrency N`, each worker thread plays one episode at a time: a plain function
    is shared by the threads, an object with `reset` is copied (`copy.deepcopy`) for every
    thread but the first, so each copy keeps the state of one episode."""

    looks = True
    agent_kind = "scripted"

    def __init__(self, spec: str, target: Callable[..., Any]) -> None:
        self.spec = spec
        self.model = spec
        self.target = target
        self._stateful = callable(getattr(target, "reset", None))
        self._lock = threading.Lock()
        self._claimed = False
        self._local = threading.local()

    def settings(self) -> dict[str, Any]:
        return {"agent": self.spec}

    def _own_target(self) -> Callable[..., Any]:
        """This thread's agent: the original for the first thread, a copy for the others."""
        if not self._stateful:
            return self.target
        own = getattr(self._local, "target", None)
        if own is None:
            with self._lock:
                first, self._claimed = not self._claimed, True
            try:
                own = self.target if first else copy.deepcopy(self.target)
            except Exception as exc:
                raise AgentError(
                    f"agent {self.spec}: cannot copy it for another thread "
                    f"({_one_line(exc)}); use --concurrency 1"
                ) from None
            self._local.target = own
        return own

    def start(self, episode: EpisodeStart) -> Player:
        target = self._own_target()
        if self._stateful:
            target.reset(episode.obs)  # type: ignore[attr-defined]
        return _ModulePlayer(self.spec, target)


class _ModulePlayer:
    def __init__(self, spec: str, target: Callable[..., Any]) -> None:
        self.spec = spec
        self.target = target

    def act(self, obs: dict[str, Any]) -> Reply:
        answer = self.target(obs)
        if not isinstance(answer, (str, Mapping)):
            raise AgentError(
                f"agent {self.spec} returned {type(answer).__name__}: an agent returns the "
                "model's text (str) or a structured action (dict)"
            )
        return Reply(answer)

    def observe(self, obs: dict[str, Any], info: dict[str, Any]) -> None:
        return None


def import_callable(spec: str) -> Callable[..., Any]:
    """`module:attr[.attr...]`, the module imported from the current directory or PYTHONPATH."""
    module_name, _, path = spec.partition(":")
    if not module_name or not path:
        raise AgentError(f"agent {spec!r}: expected module:callable")
    cwd = os.getcwd()
    if cwd not in sys.path:
        sys.path.insert(0, cwd)  # `vge` is a console script: its path has no current directory
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        if exc.name is not None and module_name.startswith(exc.name):
            raise AgentError(
                f"agent {spec}: no module named {module_name!r} in the current directory or on "
                "PYTHONPATH"
            ) from None
        raise AgentError(
            f"agent {spec}: importing {module_name} failed: {_one_line(exc)}"
        ) from None
    except Exception as exc:
        raise AgentError(
            f"agent {spec}: importing {module_name} failed: {_one_line(exc)}"
        ) from None
    target: Any = module
    for name in path.split("."):
        if not hasattr(target, name):
            raise AgentError(f"agent {spec}: {module_name} has no attribute {path!r}")
        target = getattr(target, name)
    if not callable(target):
        raise AgentError(f"agent {spec}: {path} is a {type(target).__name__}, not a callable")
    return target


def _one_line(exc: BaseException) -> str:
    return f"{type(exc).__name__}: {' '.join(str(exc).split())}"


def load_agent(spec: str, options: AgentOptions) -> LiveAgent:
    """The agent an AGENT argument names: `openai:MODEL`, `sim:PROFILE` or `module:callable`."""
    kind, sep, rest = spec.partition(":")
    if not sep or not kind or not rest:
        raise AgentError(f"agent {spec!r}: expected module:callable, sim:PROFILE or openai:MODEL")
    if kind == "openai":
        from ._vlm import OpenAIAgent

        return OpenAIAgent(rest, options)
    if kind == "sim":
        from ._sim import SimAgent

        return SimAgent(rest, options)
    return ModuleAgent(spec, import_callable(spec))


__all__ = [
    "AGENT_KINDS",
    "AgentOptions",
    "EpisodeStart",
    "LiveAgent",
    "ModuleAgent",
    "Player",
    "Reply",
    "history_text",
    "import_callable",
    "load_agent",
]
