"""One episode of `vge run`, played on a worker thread's own environment, and what comes of
it: a finished episode (its line of the episodes file), an infrastructure failure, or a task
that cannot be played.

The log of a step holds the agent's response and what the environment recorded for it
(view, feedback kind, state), so the replay of the run checks itself: zero divergent steps.
A model that refuses a request as longer than its context window ends the episode there: it
is finished, its line says `"ended": "context_exceeded"` (PROTOCOL §1.4) and the replay
scores it as a failure (§3.5).

In a continuation run (PROTOCOL §10.4) an episode first replays the source's steps before
the cut and the fix, through the same environment and recorded the same way (an agent that
keeps a history hears them through its player's `recall`), or copies the source's episode
when there is nothing to cut at.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import Any

import msgspec

import replay
from replay.env import DeviceEnv, log_step_of, no_images

from .._errors import AgentError, ContextExceededError, InfrastructureError
from ..synth import image_source
from ._agents import EpisodeStart, LiveAgent, Player
from ._continue import Cut, Source
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
        source: Source | None = None,
    ) -> None:
        self.agent = agent
        self.header = header
        self.stop = stop
        self.source = source
        """A continuation run's source and cut (None: an ordinary run)."""
        self.env = DeviceEnv(
            bench,
            lam=header.lam,
            image_source=image_source(bench.root) if agent.looks else no_images,
            run_id=header.run_id,
            model=header.model,
            agent_kind=header.agent_kind,
        )

    def play(self, episode_id: str) -> Outcome:
        cut = None
        try:
            if self.source is not None:
                cut = self.source.cut(self.env.bench, episode_id)
            obs, _ = self.env.reset(
                options={
                    "episode_id": episode_id,
                    "continuation": None if cut is None else cut.continuation,
                }
            )
        except replay.VGEError as exc:
            return Skipped(episode_id, str(exc))
        steps: list[replay.LogStep] = []
        if cut is not None and not cut.continuation.continued:
            self._copy(cut, steps)
            return self._finished(episode_id, steps, cut.ended, cut.continuation)
        player = self.agent.start(EpisodeStart(obs, self.env, self.header.run_id, self.stop))
        ended: str | None = None
        session = self.env.session
        assert session is not None
        if cut is not None:
            obs = self._prefix(cut, player, obs, steps)
        size = sum(map(_size, steps))
        while not session.done:
            if self.stop.is_set():
                raise Stopped
            try:
                reply = player.act(obs)
            except ContextExceededError:
                ended = (
                    replay.semantics.CONTEXT_EXCEEDED
                )  # an outcome of the agent's settings, not a failure
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
                obs, _, _, _, info = self.env.step(reply.action)
            except replay.ActionError as exc:
                raise AgentError(
                    f"agent {self.agent.spec}: {exc} (episode {episode_id!r}, step {len(steps)})"
                ) from None
            step = msgspec.structs.replace(
                recorded(log_step_of(reply.action), info),
                timestamp=reply.timestamp,
                prompt_tokens=reply.prompt_tokens,
                completion_tokens=reply.completion_tokens,
                latency_seconds=reply.latency_seconds,
            )
            size += _size(step)
            if size > replay.MAX_RECORD_BYTES:  # the replay would quarantine the line whole
                return Failed(
                    FailureRecord(
                        episode_id,
                        len(steps),
                        f"the answers make the episode's line longer than "
                        f"{replay.MAX_RECORD_BYTES:,} bytes, the most a record may be "
                        "(PROTOCOL §1.5)",
                    )
                )
            steps.append(step)
            player.observe(obs, info)
        return self._finished(episode_id, steps, ended, None if cut is None else cut.continuation)

    def _finished(
        self,
        episode_id: str,
        steps: list[replay.LogStep],
        ended: str | None,
        continuation: replay.Continuation | None,
    ) -> Finished:
        log = replay.EpisodeLog(
            episode_id=episode_id,
            steps=steps,
            ended=ended,  # type: ignore[arg-type]
            continuation=continuation,
        )
        session = self.env.session
        assert session is not None
        return Finished(
            episode_id, episode_line(log), log, session.termination == replay.semantics.SUCCESS
        )

    def _copy(self, cut: Cut, steps: list[replay.LogStep]) -> None:
        """The source's episode as it was, replayed for what this run records: steps after
        its termination are truncated, with nothing recorded (PROTOCOL §3.5)."""
        session = self.env.session
        assert session is not None
        for step in cut.steps:
            if session.done:
                session.advance(step)
                steps.append(step)
            else:
                steps.append(recorded(step, self.env.step(step)[4]))

    def _prefix(
        self, cut: Cut, player: Player, obs: dict[str, Any], steps: list[replay.LogStep]
    ) -> dict[str, Any]:
        """The source's steps before the cut, then the fix: played and recorded like the
        agent's own, told to an agent that keeps a history (`recall`); the observation at
        the cut."""
        recall = getattr(player, "recall", None)
        planned = [] if cut.fix is None else [log_step_of(cut.fix)]
        for step in (*cut.steps, *planned):
            before = obs
            obs, _, _, _, info = self.env.step(step)
            steps.append(recorded(step, info))
            if recall is not None:
                recall(before, step, obs, info)
        return obs


def _size(step: replay.LogStep) -> int:
    """At least the bytes a step takes in its episode's line (its unset fields included)."""
    return len(_encoder.encode(step)) + 1


def recorded(step: replay.LogStep, info: dict[str, Any]) -> replay.LogStep:
    """A step as the log carries it: the response and what the environment recorded for it
    (view, feedback kind and state after the step), so the replay has no divergent step."""
    return msgspec.structs.replace(
        step, view=info["view_after"], feedback=info["feedback_kind"], state=info["state_after"]
    )


def episode_line(log: replay.EpisodeLog) -> bytes:
    """One line of the episodes file; fields left unset are left out."""
    steps = [
        {k: v for k, v in msgspec.structs.asdict(s).items() if v is not None} for s in log.steps
    ]
    record: dict[str, Any] = {"episode_id": log.episode_id, "steps": steps}
    if log.ended is not None:
        record["ended"] = log.ended
    if log.continuation is not None:
        record["continuation"] = log.continuation
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
    return session.termination == replay.semantics.SUCCESS


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
