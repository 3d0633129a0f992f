"""The `module:callable` kind of agent: a Python callable (or object) of the user's."""

from __future__ import annotations

import copy
import importlib
import os
import sys
import threading
from collections.abc import Callable, Mapping
from typing import Any

from .._errors import AgentError
from ._agents import EpisodeStart, Player, Reply


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

    def check(self) -> None:
        """Nothing to reach: importing the callable was the check."""

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


__all__ = ["ModuleAgent", "import_callable"]
