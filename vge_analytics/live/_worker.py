"""One episode of `vge run`, played on a worker thread's own environment, and what comes of
it: a finished episode (its line of the episodes file), an infrastructure failure, or a task
that cannot be played.

The log of a step holds the agent's response and what the environment recorded for it
(view, feedback kind, state), so the replay of the run checks itself: zero divergent steps.
A model that refuses a request as longer than its context window ends the episode there: it
is finished, its line says `"ended": "context_exceeded"` (PROTOCOL §1.4) and the replay
scores it as a failure (§3.5).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import msgspec

import replay
from replay.env import DeviceEnv, log_step_of, no_images

from .._errors import AgentError, ContextExceededError, InfrastructureError
from ..synth import image_source
from ._agents import EpisodeStart, LiveAgent
from ._rundir import FailureRecord


@dataclass(frozen=True, slots=True)
class Finished:
    episode_id: str
    line: bytes
    log: replay.EpisodeLog
    success: bool


@dataclass(frozen=True, slots=True)
class Failed:
    record: FailureRecord


@dataclass(frozen=True, slots=True)
class Skipped:
    episode_id: str
    reason: str


Outcome = Finished | Failed | Skipped


class Stopped(Exception):
    """The run is being stopped (Ctrl-C, a fatal error, too many failures): leave the
    episode unplayed."""


_encoder = msgspec.json.Encoder()


class Worker:
    """Plays episodes on its own environment (one per thread)."""

    def __init__(
        self,
        agent: LiveAgent,
        bench: replay.Benchmark,
        header: replay.RunHeader,
        stop: threading.Event,
    ) -> None:
        self.agent = agent
        self.header = header
        self.stop = stop
        self.env = DeviceEnv(
            bench,
            lam=header.lam,
            image_source=image_source(bench.root) if agent.looks else no_images,
            run_id=header.run_id,
            model=header.model,
            agent_kind=header.agent_kind,
        )

    def play(self, episode_id: str) -> Outcome:
        try:
            obs, _ = self.env.reset(options={"episode_id": episode_id})
        except replay.VGEError as exc:
            return Skipped(episode_id, str(exc))
        player = self.agent.start(EpisodeStart(obs, self.env, self.header.run_id, self.stop))
        steps: list[replay.LogStep] = []
        ended: str | None = None
        terminated = False
        while True:
            if self.stop.is_set():
                raise Stopped
            try:
                reply = player.act(obs)
            except ContextExceededError:
                ended = "context_exceeded"  # an outcome of the agent's settings, not a failure
                break
            except InfrastructureError as exc:
                if self.stop.is_set():
                    raise Stopped from None
                return Failed(FailureRecord(episode_id, len(steps), str(exc)))
            except replay.VGEError:
                raise
            except Exception as exc:
                raise AgentError(
                    f"agent {self.agent.spec} raised {type(exc).__name__}: "
                    f"{' '.join(str(exc).split())} (episode {episode_id!r}, step {len(steps)})"
                ) from exc
            try:
                obs, _, terminated, truncated, info = self.env.step(reply.action)
            except replay.ActionError as exc:
                raise AgentError(
                    f"agent {self.agent.spec}: {exc} (episode {episode_id!r}, step {len(steps)})"
                ) from None
            steps.append(
                msgspec.structs.replace(
                    log_step_of(reply.action),
                    view=info["view_after"],
                    feedback=info["feedback_kind"],
                    state=info["state_after"],
                    timestamp=reply.timestamp,
                    prompt_tokens=reply.prompt_tokens,
                    completion_tokens=reply.completion_tokens,
                    latency_seconds=reply.latency_seconds,
                )
            )
            player.observe(obs, info)
            if terminated or truncated:
                break
        log = replay.EpisodeLog(episode_id=episode_id, steps=steps, ended=ended)  # type: ignore[arg-type]
        return Finished(episode_id, episode_line(log), log, terminated)


def episode_line(log: replay.EpisodeLog) -> bytes:
    """One line of the episodes file; fields left unset are left out."""
    steps = [
        {k: v for k, v in msgspec.structs.asdict(s).items() if v is not None} for s in log.steps
    ]
    record: dict = {"episode_id": log.episode_id, "steps": steps}
    if log.ended is not None:
        record["ended"] = log.ended
    return _encoder.encode(record) + b"\n"


def replayed_success(bench: replay.Benchmark, log: replay.EpisodeLog, lam: float | None) -> bool:
    """Whether a finished episode of an earlier attempt succeeded (its replay says)."""
    task = bench.tasks[log.episode_id].task
    session = replay.EpisodeSession(
        bench.machine(task.device_id),
        task,
        lam=replay.episode_lambda(task, lam),
        run_id="",
        model="",
        agent_kind="vlm",
    )
    for s in log.steps:
        session.advance(s)
    return session.termination == "success"


__all__ = [
    "Failed",
    "Finished",
    "Outcome",
    "Skipped",
    "Stopped",
    "Worker",
    "episode_line",
    "replayed_success",
]
