"""An episode as an ATIF trajectory (the Agent Trajectory Interchange Format, v1.6: the
version that brought images), in the `atif` package's models, which validate it.

- Steps: the system message and the user's first message (the request, with the view's
  picture), then one agent step per step of the episode, in log order: the response as its
  message, the parsed action as a tool call, and as observation what the environment
  answered (the feedback within the next message the agent was shown, with the picture of
  the view it then looked at). Steps logged after the episode ended have no observation.
- Per-step metrics: the tokens and cost the run recorded (latency in the metrics' `extra`),
  when the steps table has them; their sums in the trajectory's final metrics.
- The replay's verdicts: the episode's in the trajectory's `extra`, each step's in its own.
- Pictures (`--images embed`): ATIF refers to images by path; each distinct picture is
  written once per run, `DIR/<run>/images/<sha256>.jpg`, and a trajectory names it relative
  to itself, `images/<name>`.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path
from typing import Any

from atif import (
    Agent,
    ContentPart,
    FinalMetrics,
    ImageSource,
    Metrics,
    Observation,
    ObservationResult,
    Step,
    ToolCall,
    Trajectory,
)

from replay.io import make_folders, write_atomic

from ._conversation import Said, conversation
from ._pictures import Views
from ._source import Episode, Run, episode_verdict, iso_time, step_usage, step_verdict

SCHEMA_VERSION = "ATIF-v1.6"
IMAGES_DIR = "images"


class PictureFiles:
    """The pictures of one run's trajectories, written once each under `root/images/`."""

    def __init__(self, root: Path, views: Views) -> None:
        self.root = root
        self.views = views
        self.written: set[str] = set()

    def part(self, device_id: str, view: str | None) -> ContentPart | None:
        picture = self.views.picture(device_id, view) if view else None
        if picture is None:
            return None
        name = picture.name
        if name not in self.written:
            folder = make_folders(self.root, IMAGES_DIR)
            target = folder / name
            if not _regular_file(target):  # named by its content: one there is this picture
                write_atomic(target, picture.data, sync=False)  # why not synced: _durable
            self.written.add(name)
        source = ImageSource(media_type=picture.media_type, path=f"{IMAGES_DIR}/{name}")
        return ContentPart(type="image", source=source)


def _regular_file(path: Path) -> bool:
    """A file at `path`, not a link to one."""
    try:
        return stat.S_ISREG(os.lstat(path).st_mode)
    except FileNotFoundError:
        return False


def _content(said: Said, device_id: str, pictures: PictureFiles | None) -> str | list[ContentPart]:
    part = pictures.part(device_id, said.view) if pictures is not None else None
    if part is None:
        return said.text
    return [ContentPart(type="text", text=said.text), part]


def _tool_call(step: dict[str, Any]) -> ToolCall | None:
    """The parsed action as a call (None on a parse failure: there is no action)."""
    if not step["parse_ok"] or step["action_type"] is None:
        return None
    arguments: dict[str, Any] = {"params": list(step["params"] or [])}
    if step["x"] is not None and step["y"] is not None:
        arguments["coord"] = [step["x"], step["y"]]
    return ToolCall(
        tool_call_id=f"step-{step['step']}", function_name=step["action_type"], arguments=arguments
    )


def _metrics(step: dict[str, Any]) -> Metrics | None:
    usage = step_usage(step)
    if not usage:
        return None
    latency = usage.get("latency_s")
    return Metrics(
        prompt_tokens=usage.get("prompt_tokens"),
        completion_tokens=usage.get("completion_tokens"),
        cost_usd=usage.get("cost_usd"),
        extra={"latency_s": latency} if latency is not None else None,
    )


def _final_metrics(steps: list[Step], n_agent: int) -> FinalMetrics:
    measured = [s.metrics for s in steps if s.metrics is not None]

    def total(values: list[Any]) -> Any:
        present = [v for v in values if v is not None]
        return sum(present) if present else None

    latency = total([(m.extra or {}).get("latency_s") for m in measured])
    return FinalMetrics(
        total_prompt_tokens=total([m.prompt_tokens for m in measured]),
        total_completion_tokens=total([m.completion_tokens for m in measured]),
        total_cost_usd=total([m.cost_usd for m in measured]),
        total_steps=n_agent,
        extra={"total_latency_s": latency} if latency is not None else None,
    )


def _agent(run: Run) -> Agent:
    version = run.meta.get("version")
    return Agent(
        name=run.agent,
        version=str(version) if version is not None else "unrecorded",
        model_name=run.model,
        extra={
            "run_id": run.run_id,
            "agent_kind": run.agent_kind,
            "lambda": run.lam,
            "meta": run.meta,
        },
    )


def trajectory(
    run: Run, episode: Episode, device_views: tuple[str, ...], pictures: PictureFiles | None
) -> Trajectory:
    """The episode as a trajectory; `pictures`: where its pictures go (None: no pictures)."""
    talk = conversation(episode, device_views)
    device = episode.row["device_id"]
    steps = [
        Step(step_id=1, source="system", message=talk.system),
        Step(step_id=2, source="user", message=_content(talk.opening, device, pictures)),
    ]
    for exchange in talk.exchanges:
        step = exchange.step
        call = _tool_call(step)
        observation = None
        if exchange.reply is not None:
            result = ObservationResult(
                source_call_id=call.tool_call_id if call is not None else None,
                content=_content(exchange.reply, device, pictures),
                extra={
                    "feedback_kind": step["feedback_kind"],
                    "feedback_text": step["feedback_text"],
                },
            )
            observation = Observation(results=[result])
        steps.append(
            Step(
                step_id=len(steps) + 1,
                timestamp=iso_time(step["timestamp"]),
                source="agent",
                message=exchange.answer,
                tool_calls=[call] if call is not None else None,
                observation=observation,
                metrics=_metrics(step),
                extra=step_verdict(step),
            )
        )
    return Trajectory(
        schema_version=SCHEMA_VERSION,
        session_id=f"{run.run_id}/{episode.episode_id}",
        agent=_agent(run),
        steps=steps,
        final_metrics=_final_metrics(steps, len(talk.exchanges)),
        extra={
            "run_id": run.run_id,
            "instructions": episode.instructions,
            **episode_verdict(episode),
        },
    )


def trajectory_json(traj: Trajectory) -> bytes:
    """The trajectory as a file holds it: JSON, unset fields left out, indented."""
    return traj.model_dump_json(exclude_none=True, indent=2).encode("utf-8") + b"\n"


__all__ = [
    "IMAGES_DIR",
    "SCHEMA_VERSION",
    "PictureFiles",
    "trajectory",
    "trajectory_json",
]
