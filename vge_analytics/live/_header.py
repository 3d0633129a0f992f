"""What `vge run` was asked and what it has done: its options, its running totals, and the
run.json header made of both (PROTOCOL §10.2), with the rule of `--resume` (the settings of
the run must stay; its totals, its selection and how the model is reached may change)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import msgspec

import replay

from .._errors import RunDirError
from ._agents import AGENT_KINDS, LiveAgent
from ._continue import ContinueFrom

TOTAL_KEYS = replay.semantics.RUN_TOTALS
"""Keys of run.json's meta that count what the run did or was asked to play (the others are
its settings). The selection is one of them: `--resume` may extend it."""
CONNECTION_KEYS = ("base_url", "request_timeout_seconds", "max_response_bytes", "retries")
"""Settings of how the model is reached, which `--resume` may change (a server on a new
address); every other setting must stay as the run was started."""


class RunOptions(msgspec.Struct, frozen=True):
    """Everything `vge run` was asked, besides the agent."""

    bench: Path
    out: Path
    run_id: str | None = None
    """None: the name of `out`."""
    model: str | None = None
    """None: the agent's own name for its model."""
    agent_kind: str | None = None
    """None: the agent's kind (openai: vlm, sim: the profile's, module: scripted)."""
    lam: float | None = None
    """The run's λ (None: 5); a task's own λ wins (PROTOCOL §3.5)."""
    episodes: tuple[str, ...] | None = None
    limit: int | None = None
    concurrency: int = 1
    resume: bool = False
    prompt_price: float | None = None
    """USD per million prompt tokens."""
    completion_price: float | None = None
    """USD per million completion tokens."""
    max_consecutive_failures: int = 10
    """Infrastructure failures in a row (across episodes) that stop the run; 0: never."""
    continuation: ContinueFrom | None = None
    """A continuation run (`--from`, `--at`, `--fix`; PROTOCOL §10.4)."""


@dataclass(slots=True)
class Counters:
    """What the run has done so far (the progress bar's figures)."""

    selected: int = 0
    finished: int = 0
    succeeded: int = 0
    context_exceeded: int = 0
    """Finished episodes the model's context window ended (`context_exceeded`)."""
    failures: int = 0
    skipped: int = 0
    source_unread: int = 0
    """A continuation's source lines that are not episode records (not continued)."""
    steps: int = 0
    prompt_tokens: int = 0
    completion_tokens: int = 0
    latency_seconds: float = 0.0
    has_usage: bool = False
    prices: replay.semantics.Prices = replay.semantics.Prices()

    @property
    def cost_usd(self) -> float | None:
        """The run's tokens at its prices, by the rule the replay prices each step with."""
        if not self.has_usage:
            return None
        return replay.semantics.usage_cost(self.prompt_tokens, self.completion_tokens, self.prices)

    def add(self, log: replay.EpisodeLog, success: bool) -> None:
        self.finished += 1
        self.succeeded += success
        self.context_exceeded += log.ended == replay.semantics.CONTEXT_EXCEEDED
        self.steps += len(log.steps)
        for s in log.steps:
            if s.prompt_tokens is not None or s.completion_tokens is not None:
                self.has_usage = True
            self.prompt_tokens += s.prompt_tokens or 0
            self.completion_tokens += s.completion_tokens or 0
            self.latency_seconds += s.latency_seconds or 0.0


def run_header(agent: LiveAgent, options: RunOptions, counters: Counters) -> replay.RunHeader:
    agent_kind = options.agent_kind or agent.agent_kind
    if agent_kind not in AGENT_KINDS:
        raise RunDirError(f"--agent-kind must be one of {', '.join(AGENT_KINDS)}")
    selected = counters.selected
    meta: dict[str, Any] = dict(agent.settings())
    if options.continuation is not None:  # a setting: --resume must keep it
        meta["counterfactual"] = options.continuation.meta()
    meta["episodes_selected"] = selected
    # The prices stay in run.json: the replay prices every step with them (PROTOCOL §1.4).
    if options.prompt_price is not None:
        meta[replay.PROMPT_PRICE_KEY] = options.prompt_price
    if options.completion_price is not None:
        meta[replay.COMPLETION_PRICE_KEY] = options.completion_price
    meta |= {
        "episodes": counters.finished,
        "infrastructure_failures": counters.failures,
        "tasks_skipped": counters.skipped,
        "complete": counters.finished + counters.skipped == selected and not counters.source_unread,
        "steps": counters.steps,
    }
    if counters.source_unread:
        meta["source_lines_unread"] = counters.source_unread
    if counters.has_usage:
        meta["prompt_tokens"] = counters.prompt_tokens
        meta["completion_tokens"] = counters.completion_tokens
        meta["latency_seconds"] = round(counters.latency_seconds, 3)
        if counters.cost_usd is not None:
            meta["cost_usd"] = round(counters.cost_usd, 6)
    return replay.RunHeader(
        run_id=options.run_id or options.out.resolve().name,
        model=options.model or agent.model,
        agent_kind=agent_kind,  # type: ignore[arg-type]
        lam=replay.run_lambda(options.lam),
        meta=meta,
    )


def _settings(header: replay.RunHeader) -> dict[str, Any]:
    return {
        "run_id": header.run_id,
        "model": header.model,
        "agent_kind": header.agent_kind,
        "lambda": header.lam,
        **{
            k: v for k, v in header.meta.items() if k not in TOTAL_KEYS and k not in CONNECTION_KEYS
        },
    }


def check_resume(old: replay.RunHeader, new: replay.RunHeader) -> None:
    """`--resume` keeps the settings the run was started with (one line naming each one
    that differs)."""
    before, now = _settings(old), _settings(new)
    changed = sorted(k for k in before.keys() | now.keys() if before.get(k) != now.get(k))
    if changed:
        said = "; ".join(f"{k}: {before.get(k)!r} then, {now.get(k)!r} now" for k in changed)
        raise RunDirError(f"--resume with other settings than the run was started with ({said})")


__all__ = [
    "CONNECTION_KEYS",
    "TOTAL_KEYS",
    "Counters",
    "RunOptions",
    "check_resume",
    "run_header",
]
