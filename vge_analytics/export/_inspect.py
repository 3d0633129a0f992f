"""A run as an Inspect eval: its header (spec, plan), one sample per episode, each sample's
summary, and its results (the run's metrics), as the plain JSON values of `inspect_ai`'s
log schema (version 2), ready to encode.

- A sample's input is the instruction (each goal's, in order); its target, the goal states;
  its messages, the conversation (`_conversation`) with the view's picture beside each text
  the agent was shown (`--images embed`); its scores, the replay's verdicts (`success`,
  `spl`, `state_f1`, `goals_completed`); its metadata, the rest of the episode's row, the
  error types of its steps and its divergence. Each answer carries its step's verdict (and
  the tokens, latency and cost the run recorded, when the steps table has them).
- Identifiers are derived from the run and episode ids, times are the recorded ones: the
  same OUT gives the same log.

Why not `inspect_ai`'s classes: building a sample as pydantic models, validating it and
dumping it again (twice, as its recorder does) cost four times reading the episode. The
values here are what those models dump (`exclude_none`, fields in the models' order, the
defaults they write); `tests/vge_analytics/export/test_inspect_schema.py` reads every
member back with `inspect_ai` and checks that its models dump the same bytes.
"""

from __future__ import annotations

import hashlib
import textwrap
from collections.abc import Mapping
from datetime import datetime
from typing import Any

import mmh3

from ..metrics import MetricSet
from ._conversation import Said, conversation
from ._pictures import Views
from ._source import EPOCH, Episode, Run, episode_verdict, iso_time, step_usage, step_verdict

TASK = "vgebench"
SCORER = "vge_replay"
"""What the scores and metrics are attributed to: the replay (PROTOCOL §3 to §6)."""
SCORES: tuple[str, ...] = ("success", "spl", "state_f1", "goals_completed")
LOG_VERSION = 2
"""The version of inspect_ai's log schema these values follow."""
ATTACHMENT = "attachment://"
SUMMARY_TEXT = 5120
"""inspect_ai's bounds on what a sample's summary keeps: the input's characters..."""
SUMMARY_FIELD = 1024
"""... and a metadata value's or a score answer's (in JSON, indented, for a container)."""

Json = dict[str, Any]


def short_id(*parts: str) -> str:
    """A stable identifier of 22 characters (the length of Inspect's own ids) for `parts`."""
    return hashlib.blake2b("\0".join(parts).encode("utf-8"), digest_size=11).hexdigest()


def utc_time(seconds: float | None) -> str | None:
    """A recorded time as Inspect writes it: `iso_time`'s, to the microsecond."""
    text = iso_time(seconds)
    return datetime.fromisoformat(text).isoformat() if text is not None else None


def eval_spec(run: Run, images: str) -> Json:
    """The log's header: the run as an eval of the `vgebench` task by the run's model."""
    return {
        "eval_id": short_id("eval", run.run_id),
        "run_id": short_id("run", run.run_id),
        "created": utc_time(run.first_time) or EPOCH,
        "task": TASK,
        "task_id": short_id("task", run.run_id),
        "task_version": 0,
        "task_display_name": f"{TASK} · {run.run_id}",
        "task_attribs": {},
        "task_args": {},
        "task_args_passed": {},
        "solver_args_passed": {},
        "tags": [run.run_id, run.agent_kind],
        "dataset": {
            "name": getattr(run.bench, "name", None) or str(run.bench),
            "location": str(run.bench),
            "samples": len(run.episodes),
        },
        "model": run.model,
        "model_generate_config": {},
        "model_args": {},
        "config": {},
        "packages": {},
        "metadata": {
            "vge_run_id": run.run_id,
            "agent_kind": run.agent_kind,
            "agent": run.agent,
            "lambda": run.lam,
            "run_meta": run.meta,
            "engine_version": run.engine_version,
            "exported_by": "vge export",
            "images": images,
        },
    }


def eval_plan(run: Run) -> Json:
    """The agent that played the run, with the settings its run recorded."""
    step = {"solver": run.agent, "params": dict(run.meta), "params_passed": dict(run.meta)}
    return {"name": "plan", "steps": [step], "config": {}}


def eval_results(run: Run, metrics: MetricSet) -> Json:
    """The run's metrics over the exported episodes (a metric without a value is left out)."""
    found: dict[str, Json] = {}
    for name, value in run.metrics.items():
        if value is None:
            continue
        m = metrics.get(name)
        found[name] = {
            "name": name,
            "value": value,
            "params": {},
            "metadata": {"title": m.title, "direction": m.direction, "unit": m.unit},
        }
    n = len(run.episodes)
    score = {"name": "vge", "scorer": SCORER, "scored_samples": n, "params": {}, "metrics": found}
    return {"total_samples": n, "completed_samples": n, "scores": [score]}


def eval_stats(run: Run, usage: Json | None) -> Json:
    """Recorded times of the run's first and last steps, and the usage its steps recorded."""
    return {
        "started_at": utc_time(run.first_time) or "",
        "completed_at": utc_time(run.last_time) or "",
        "model_usage": {run.model: usage} if usage is not None else {},
        "role_usage": {},
        "connection_limit_history": [],
    }


def eval_header(spec: Json, plan: Json, results: Json, stats: Json) -> Json:
    """The finished log's header (`header.json`)."""
    return {
        "version": LOG_VERSION,
        "status": "success",
        "eval": spec,
        "plan": plan,
        "results": results,
        "stats": stats,
        "invalidated": False,
        "tags": sorted(set(spec["tags"])),  # EvalLog keeps its tags as a sorted set
        "metadata": spec["metadata"],
    }


def model_usage(prompt: int, completion: int, cost: float | None) -> Json:
    """Inspect's `ModelUsage` of a call (or a sum of calls)."""
    usage: Json = {
        "input_tokens": prompt,
        "output_tokens": completion,
        "total_tokens": prompt + completion,
    }
    if cost is not None:
        usage["total_cost"] = cost
    return usage


def add_usage(a: Json, b: Json) -> Json:
    """`ModelUsage.__add__`: token counts add up, a cost known on one side is kept."""
    costs = [u["total_cost"] for u in (a, b) if "total_cost" in u]
    cost = costs[0] + costs[1] if len(costs) == 2 else (costs[0] if costs else None)
    return model_usage(
        a["input_tokens"] + b["input_tokens"], a["output_tokens"] + b["output_tokens"], cost
    )


def sample_usage(episode: Episode) -> Json | None:
    """The tokens and cost the episode's steps recorded (None when none did)."""
    recorded = [step_usage(s) for s in episode.steps]
    if not any(recorded):
        return None

    def total(key: str) -> int:
        return int(sum(u.get(key, 0) for u in recorded))

    costs = [u["cost_usd"] for u in recorded if "cost_usd" in u]
    return model_usage(
        total("prompt_tokens"), total("completion_tokens"), sum(costs) if costs else None
    )


def _scores(verdict: Mapping[str, Any]) -> dict[str, Json]:
    n, done = verdict["n_goals"], verdict["goals_completed"]
    return {
        "success": {
            "value": 1.0 if verdict["success"] else 0.0,
            "answer": verdict["termination"],
            "history": [],
        },
        "spl": {"value": float(verdict["spl"]), "history": []},
        "state_f1": {"value": float(verdict["state_f1"]), "history": []},
        "goals_completed": {"value": int(done), "answer": f"{done} of {n}", "history": []},
    }


class _Attachments:
    """The pictures of a sample, each stored once under its hash, as inspect_ai's
    `condense_sample` stores them (`attachment://<murmur3 of the data URL>`)."""

    def __init__(self) -> None:
        self.stored: dict[str, str] = {}

    def ref(self, url: str) -> str:
        h1, h2 = mmh3.hash64(url.encode("utf-8", errors="backslashreplace"))
        key = f"{h1 & 0xFFFFFFFFFFFFFFFF:016x}{h2 & 0xFFFFFFFFFFFFFFFF:016x}"
        self.stored.setdefault(key, url)
        return ATTACHMENT + key


def _user(
    said: Said, device_id: str, views: Views | None, message_id: str, held: _Attachments
) -> tuple[Json, int]:
    """The message, and the characters it holds (its text and picture: what it weighs)."""
    picture = views.picture(device_id, said.view) if views is not None and said.view else None
    if picture is None:
        return {"id": message_id, "content": said.text, "role": "user"}, len(said.text)
    url = picture.data_url
    content = [
        {"type": "text", "text": said.text},
        {"type": "image", "image": held.ref(url), "detail": "auto"},
    ]
    return {"id": message_id, "content": content, "role": "user"}, len(said.text) + len(url)


def eval_sample(
    run: Run, episode: Episode, device_views: tuple[str, ...], views: Views | None
) -> tuple[Json, int]:
    """The episode as a sample, and the characters of its messages (text and pictures);
    `views`: the pictures to embed (None: no pictures)."""
    base = short_id(run.run_id, episode.episode_id)
    # the messages' ids: the sample's, numbered (one hash per sample, not per message)
    ids = (f"{base}-{n}" for n in range(2 * len(episode.steps) + 2))
    talk = conversation(episode, device_views)
    device = episode.row["device_id"]
    held = _Attachments()
    messages: list[Json] = [{"id": next(ids), "content": talk.system, "role": "system"}]
    opening, size = _user(talk.opening, device, views, next(ids), held)
    messages.append(opening)
    size += len(talk.system)
    last: Json | None = None
    for exchange in talk.exchanges:
        last = {
            "id": next(ids),
            "content": exchange.answer,
            "source": "generate",
            "metadata": {**step_verdict(exchange.step), **step_usage(exchange.step)},
            "role": "assistant",
            "model": run.model,
        }
        messages.append(last)
        size += len(exchange.answer)
        if exchange.reply is not None:
            reply, more = _user(exchange.reply, device, views, next(ids), held)
            messages.append(reply)
            size += more
    verdict = episode_verdict(episode)
    usage = sample_usage(episode)
    times = [s["timestamp"] for s in episode.steps if s["timestamp"] is not None]
    choices = [{"message": last, "stop_reason": "stop"}] if last else []
    sample: Json = {
        "id": episode.episode_id,
        "epoch": 1,
        "input": "\n".join(episode.instructions),
        "target": list(episode.row["goals"]),
        "messages": messages,
        "output": {
            "model": run.model,
            "choices": choices,
            "completion": last["content"] if last else "",
        },
        "scores": _scores(verdict),
        "metadata": {k: v for k, v in verdict.items() if k not in SCORES},
        "store": {},
        "events": [],
        "model_usage": {run.model: usage} if usage is not None else {},
        "role_usage": {},
    }
    if times:
        sample["started_at"] = utc_time(min(times))
        sample["completed_at"] = utc_time(max(times))
    sample["uuid"] = base
    sample["attachments"] = held.stored
    if views is not None:  # what condense_sample adds, whether or not a picture was found
        sample["events_data"] = {"messages": [], "calls": []}
    return sample, size


def sample_summary(sample: Json, encode_indented: Any) -> Json:
    """The sample's entry in the log's index, thinned as `EvalSampleSummary` thins it: text
    cut, metadata values over `SUMMARY_FIELD` characters of JSON replaced by a note.
    `encode_indented(value)`: the value as inspect_ai measures it (JSON, indent 2)."""
    summary: Json = {
        "id": sample["id"],
        "epoch": sample["epoch"],
        "input": _truncate(sample["input"]),
        "target": [_truncate(t) for t in sample["target"]],
        "metadata": {k: _thin(v, encode_indented) for k, v in sample["metadata"].items()},
        "scores": {k: _thin_score(s) for k, s in sample["scores"].items()},
        "model_usage": sample["model_usage"],
        "role_usage": sample["role_usage"],
    }
    for key in ("started_at", "completed_at"):
        if key in sample:
            summary[key] = sample[key]
    summary.update(uuid=sample["uuid"], completed=True, message_count=len(sample["messages"]))
    return summary


def _truncate(text: str) -> str:
    return text[:SUMMARY_TEXT] + "...\n(content truncated)" if len(text) > SUMMARY_TEXT else text


def _thin_text(text: str) -> str:
    """inspect_ai's `thin_text`: whitespace collapsed, shortened to SUMMARY_FIELD characters
    at a word's end (`textwrap.shorten`, which a text that fits once collapsed skips)."""
    text = text[: 8 * SUMMARY_FIELD]
    collapsed = " ".join(text.split())
    if len(collapsed) <= SUMMARY_FIELD:
        return collapsed
    return textwrap.shorten(text, width=SUMMARY_FIELD, placeholder="...")


def _thin(value: Any, encode_indented: Any) -> Any:
    if isinstance(value, int | float | bool):
        return value
    if isinstance(value, str):
        return _thin_text(value)
    if len(encode_indented(value)) <= SUMMARY_FIELD:
        return value
    return "Key removed from summary (> 1k)"


def _thin_score(score: Json) -> Json:
    thinned: Json = {"value": score["value"]}
    if "answer" in score:
        thinned["answer"] = _thin_text(score["answer"])
    thinned["history"] = []
    return thinned


__all__ = [
    "LOG_VERSION",
    "SCORER",
    "SCORES",
    "TASK",
    "add_usage",
    "eval_header",
    "eval_plan",
    "eval_results",
    "eval_sample",
    "eval_spec",
    "eval_stats",
    "sample_summary",
    "sample_usage",
    "short_id",
    "utc_time",
]
