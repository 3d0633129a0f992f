"""A run as an Inspect eval: its header (`EvalSpec`, `EvalPlan`), one `EvalSample` per episode
and its results (the run's metrics), in `inspect_ai`'s own log classes.

- A sample's input is the instruction (each goal's, in order); its target, the goal states;
  its messages, the conversation (`_conversation`) with the view's picture beside each text
  the agent was shown (`--images embed`); its scores, the replay's verdicts (`success`,
  `spl`, `state_f1`, `goals_completed`); its metadata, the rest of the episode's row, the
  error types of its steps and its divergence. Each answer carries its step's verdict (and
  the tokens, latency and cost the run recorded, when the steps table has them).
- Identifiers are derived from the run and episode ids, times are the recorded ones: the
  same OUT gives the same log.
"""

from __future__ import annotations

import base64
import hashlib
from collections.abc import Mapping
from typing import Any

from inspect_ai.log import (
    EvalConfig,
    EvalDataset,
    EvalMetric,
    EvalPlan,
    EvalPlanStep,
    EvalResults,
    EvalSample,
    EvalScore,
    EvalSpec,
    EvalStats,
)
from inspect_ai.model import (
    ChatCompletionChoice,
    ChatMessage,
    ChatMessageAssistant,
    ChatMessageSystem,
    ChatMessageUser,
    Content,
    ContentImage,
    ContentText,
    ModelOutput,
    ModelUsage,
)
from inspect_ai.scorer import Score

from ..metrics import MetricSet
from ._conversation import Said, conversation
from ._pictures import Views
from ._source import EPOCH, Episode, Run, episode_verdict, iso_time, step_usage, step_verdict

TASK = "vgebench"
SCORER = "vge_replay"
"""What the scores and metrics are attributed to: the replay (PROTOCOL §3 to §6)."""
SCORES: tuple[str, ...] = ("success", "spl", "state_f1", "goals_completed")


def short_id(*parts: str) -> str:
    """A stable identifier of 22 characters (the length of Inspect's own ids) for `parts`."""
    return hashlib.blake2b("\0".join(parts).encode("utf-8"), digest_size=11).hexdigest()


def eval_spec(run: Run, images: str) -> EvalSpec:
    """The log's header: the run as an eval of the `vgebench` task by the run's model."""
    return EvalSpec(
        eval_id=short_id("eval", run.run_id),
        run_id=short_id("run", run.run_id),
        created=iso_time(run.first_time) or EPOCH,
        task=TASK,
        task_id=short_id("task", run.run_id),
        task_display_name=f"{TASK} · {run.run_id}",
        dataset=EvalDataset(
            name=getattr(run.bench, "name", None) or str(run.bench),
            location=str(run.bench),
            samples=len(run.episodes),
        ),
        model=run.model,
        config=EvalConfig(),
        tags=[run.run_id, run.agent_kind],
        metadata={
            "vge_run_id": run.run_id,
            "agent_kind": run.agent_kind,
            "agent": run.agent,
            "lambda": run.lam,
            "run_meta": run.meta,
            "engine_version": run.engine_version,
            "exported_by": "vge export",
            "images": images,
        },
    )


def eval_plan(run: Run) -> EvalPlan:
    """The agent that played the run, with the settings its run recorded."""
    return EvalPlan(steps=[EvalPlanStep(solver=run.agent, params=dict(run.meta))])


def eval_results(run: Run, metrics: MetricSet) -> EvalResults:
    """The run's metrics over the exported episodes (a metric without a value is left out)."""
    found: dict[str, EvalMetric] = {}
    for name, value in run.metrics.items():
        if value is None:
            continue
        m = metrics.get(name)
        found[name] = EvalMetric(
            name=name,
            value=value,
            metadata={"title": m.title, "direction": m.direction, "unit": m.unit},
        )
    n = len(run.episodes)
    return EvalResults(
        total_samples=n,
        completed_samples=n,
        scores=[EvalScore(name="vge", scorer=SCORER, scored_samples=n, metrics=found)],
    )


def eval_stats(run: Run, usage: ModelUsage | None) -> EvalStats:
    """Recorded times of the run's first and last steps, and the usage its steps recorded."""
    return EvalStats(
        started_at=iso_time(run.first_time) or "",
        completed_at=iso_time(run.last_time) or "",
        model_usage={run.model: usage} if usage is not None else {},
    )


def sample_usage(episode: Episode) -> ModelUsage | None:
    """The tokens and cost the episode's steps recorded (None when none did)."""
    recorded = [step_usage(s) for s in episode.steps]
    if not any(recorded):
        return None

    def total(key: str) -> int:
        return int(sum(u.get(key, 0) for u in recorded))

    costs = [u["cost_usd"] for u in recorded if "cost_usd" in u]
    prompt, completion = total("prompt_tokens"), total("completion_tokens")
    return ModelUsage(
        input_tokens=prompt,
        output_tokens=completion,
        total_tokens=prompt + completion,
        total_cost=sum(costs) if costs else None,
    )


def _scores(verdict: Mapping[str, Any]) -> dict[str, Score]:
    n, done = verdict["n_goals"], verdict["goals_completed"]
    return {
        "success": Score(value=1.0 if verdict["success"] else 0.0, answer=verdict["termination"]),
        "spl": Score(value=float(verdict["spl"])),
        "state_f1": Score(value=float(verdict["state_f1"])),
        "goals_completed": Score(value=int(done), answer=f"{done} of {n}"),
    }


def _user(said: Said, device_id: str, views: Views | None, message_id: str) -> ChatMessageUser:
    picture = views.picture(device_id, said.view) if views is not None and said.view else None
    if picture is None:
        return ChatMessageUser(id=message_id, content=said.text)
    url = f"data:{picture.media_type};base64," + base64.b64encode(picture.data).decode("ascii")
    content: list[Content] = [ContentText(text=said.text), ContentImage(image=url)]
    return ChatMessageUser(id=message_id, content=content)


def eval_sample(
    run: Run, episode: Episode, device_views: tuple[str, ...], views: Views | None
) -> EvalSample:
    """The episode as a sample; `views`: the pictures to embed (None: no pictures)."""
    base = short_id(run.run_id, episode.episode_id)
    # the messages' ids: the sample's, numbered (one hash per sample, not per message)
    ids = (f"{base}-{n}" for n in range(2 * len(episode.steps) + 2))
    talk = conversation(episode, device_views)
    device = episode.row["device_id"]
    messages: list[ChatMessage] = [
        ChatMessageSystem(id=next(ids), content=talk.system),
        _user(talk.opening, device, views, next(ids)),
    ]
    last: ChatMessageAssistant | None = None
    for exchange in talk.exchanges:
        last = ChatMessageAssistant(
            id=next(ids),
            content=exchange.answer,
            model=run.model,
            source="generate",
            metadata={**step_verdict(exchange.step), **step_usage(exchange.step)},
        )
        messages.append(last)
        if exchange.reply is not None:
            messages.append(_user(exchange.reply, device, views, next(ids)))
    verdict = episode_verdict(episode)
    usage = sample_usage(episode)
    times = [s["timestamp"] for s in episode.steps if s["timestamp"] is not None]
    return EvalSample(
        id=episode.episode_id,
        epoch=1,
        input="\n".join(episode.instructions),
        target=list(episode.row["goals"]),
        messages=messages,
        output=ModelOutput(
            model=run.model,
            choices=[ChatCompletionChoice(message=last, stop_reason="stop")] if last else [],
            completion=last.text if last else "",
        ),
        scores=_scores(verdict),
        metadata={k: v for k, v in verdict.items() if k not in SCORES},
        model_usage={run.model: usage} if usage is not None else {},
        started_at=iso_time(min(times)) if times else None,
        completed_at=iso_time(max(times)) if times else None,
        uuid=base,
    )


__all__ = [
    "SCORER",
    "SCORES",
    "TASK",
    "eval_plan",
    "eval_results",
    "eval_sample",
    "eval_spec",
    "eval_stats",
    "sample_usage",
    "short_id",
]
