"""What the replay says about an episode and its steps, and what the run recorded of a
step's cost, as plain JSON values both formats carry (Inspect's scores and metadata, ATIF's
`extra` and metrics)."""

from __future__ import annotations

from collections import Counter
from typing import Any

from ._source import STEP_METRICS, STEP_VERDICT, Episode

RUN_COLUMNS = ("run_id", "model", "agent_kind")
"""Columns every row repeats; the run says them once."""


def episode_verdict(episode: Episode) -> dict[str, Any]:
    """The episode's row (PROTOCOL §7.3, without the run's columns), the error types of its
    scored steps with their counts, and its diverged steps by field."""
    row = {k: v for k, v in episode.row.items() if k not in RUN_COLUMNS}
    scored = [s for s in episode.steps if not s["truncated"]]
    errors = Counter(s["error_type"] for s in scored if s["error_type"] is not None)
    fields = Counter(f for s in scored for f in s["diverged_fields"] or ())
    return {
        **row,
        "error_types": dict(sorted(errors.items())),
        "diverged_by_field": dict(sorted(fields.items())),
    }


def step_verdict(step: dict[str, Any]) -> dict[str, Any]:
    """The step's replay columns (`STEP_VERDICT`) that have a value."""
    return {k: step[k] for k in STEP_VERDICT if step.get(k) is not None}


def step_usage(step: dict[str, Any]) -> dict[str, Any]:
    """What the run recorded of the step's model call: tokens, latency, cost (the steps
    table's columns, when it has them and they are not null)."""
    return {k: step[k] for k in STEP_METRICS if step.get(k) is not None}


__all__ = ["episode_verdict", "step_usage", "step_verdict"]
