"""What an export reads from OUT: the selected runs, their headers and metrics, and their
episodes one batch at a time; and what both formats carry of them as plain JSON values
(Inspect's scores and metadata, ATIF's `extra` and metrics): the replay's verdict of an
episode and of each step, what the run recorded of a step's cost, and the recorded times in
ISO 8601 (no clock is read).

Everything is read through the store and the metrics (`store.runs/episodes/goals/steps`,
`metrics.metrics`, and one query of ours on `store.open_store`'s locked-down views), the
manifest through `replay.read_manifest`, and the benchmark's location through
`store.bench_dir`, so an export sees OUT exactly as `vge sql` and the dashboard do. Memory stays bounded whatever the size of a run: a run's episodes are fetched
a batch at a time (their rows, goals and steps; a few megabytes of text at most, or one
episode when it alone holds more), never the run at once. What a batch holds is known
beforehand: one query per run measures each episode's text inside DuckDB, without fetching
it.
"""

from __future__ import annotations

import json
import math
from collections import Counter
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from itertools import groupby
from pathlib import Path
from typing import Any, NamedTuple

import replay
from replay.io import STEPS_TABLE

from .. import store
from .._errors import OutputDirError, UnknownRunError
from .._nearest import nearest_hint
from ..metrics import metrics as computed_metrics

BATCH_STEPS = 5000
"""Steps fetched per query (the episodes whose steps add up to it); each query costs about
50 ms on the full synthetic benchmark (it scans the steps table's ids)..."""
BATCH_BYTES = 4 * 1024**2
"""... or fewer, once their responses and feedback add up to this many bytes of text."""
BATCH_EPISODES = 500
"""At most this many episodes per query (goal rows and the list of ids bound to the query)."""

STEP_VERDICT: tuple[str, ...] = (
    "step",
    "goal_index",
    "view_before",
    "view_after",
    "action_type",
    "x",
    "y",
    "params",
    "parse_ok",
    "parse_detail",
    "feedback_kind",
    "state_before",
    "state_after",
    "transition_component",
    "dangerous",
    "completed_goals",
    "progress",
    "error_type",
    "error_group",
    "switch_class",
    "truncated",
    "diverged",
    "diverged_fields",
)
"""What the replay says of a step (PROTOCOL §7.2), kept with it in both formats."""
STEP_COLUMNS: tuple[str, ...] = (
    *STEP_VERDICT,
    "dashboard_unlocked",
    "action_raw",
    "output",
    "feedback_text",
    "timestamp",
)
"""The step columns an export reads: the verdict, and what the conversation is made of."""

STEP_METRICS: tuple[str, ...] = ("prompt_tokens", "completion_tokens", "latency_s", "cost_usd")
"""Per-step usage columns, read when the steps table has them (null where not recorded)."""


class Contents(NamedTuple):
    """What an episode holds, as far as reading it goes."""

    episode_id: str
    steps: int
    text_bytes: int
    """Bytes of its responses and feedback texts: most of what its rows weigh."""
    first_time: float | None
    last_time: float | None


@dataclass(frozen=True)
class Run:
    """A run to export: its header (runs table), where it was replayed from, and its
    metrics over the selected episodes."""

    run_id: str
    model: str
    agent_kind: str
    lam: float
    meta: dict[str, Any]
    engine_version: str
    bench: Path | replay.Location
    episodes: tuple[Contents, ...]
    """The selected episodes, by id."""
    metrics: dict[str, float | None]

    @property
    def agent(self) -> str:
        """What played the run: `vge run`'s agent spec when its run.json records it (e.g.
        `openai:gpt-4o`, `sim:sim-vlm-f`), else the run's agent kind."""
        agent = self.meta.get("agent")
        return agent if isinstance(agent, str) and agent else self.agent_kind

    @property
    def first_time(self) -> float | None:
        """The earliest recorded step time of the exported episodes (seconds since the
        epoch), if any: the only times an export writes."""
        return min((c.first_time for c in self.episodes if c.first_time is not None), default=None)

    @property
    def last_time(self) -> float | None:
        return max((c.last_time for c in self.episodes if c.last_time is not None), default=None)


@dataclass(frozen=True)
class Episode:
    """One replayed episode: its row of the episodes table, its goals by index and its steps
    in log order (truncated ones included)."""

    run_id: str
    row: dict[str, Any]
    goals: list[dict[str, Any]]
    steps: list[dict[str, Any]]

    @property
    def episode_id(self) -> str:
        return self.row["episode_id"]

    @property
    def instructions(self) -> list[str]:
        """The instruction of each goal, in order ('' where the task gave none)."""
        return [g["instruction"] or "" for g in self.goals]


@dataclass(frozen=True)
class Source:
    """An OUT directory opened for export, with the runs and episodes selected."""

    out: str
    runs: list[Run]
    step_columns: tuple[str, ...]
    """STEP_COLUMNS, then those of STEP_METRICS the steps table has."""

    @property
    def episodes(self) -> int:
        return sum(len(r.episodes) for r in self.runs)

    def episodes_of(self, run: Run) -> Iterator[Episode]:
        """The run's selected episodes in episode id order, fetched a batch at a time."""
        for batch in _batches(run.episodes):
            where = {"run_id": run.run_id, "episode_id": batch}
            rows = store.episodes(self.out, where=where).to_dicts()
            goals = _by_episode(store.goals(self.out, where=where).to_dicts())
            steps = _by_episode(
                store.steps(
                    self.out, where=where, columns=["episode_id", *self.step_columns]
                ).to_dicts()
            )
            for row in rows:
                key = row["episode_id"]
                yield Episode(run.run_id, row, goals.get(key, []), steps.get(key, []))


def _batches(episodes: Sequence[Contents]) -> Iterator[list[str]]:
    """The episodes' ids in order, cut into batches of at most BATCH_BYTES of text,
    BATCH_STEPS steps and BATCH_EPISODES episodes (a larger episode is a batch of its own)."""
    batch: list[str] = []
    steps = size = 0
    for episode in episodes:
        full = steps + episode.steps > BATCH_STEPS or size + episode.text_bytes > BATCH_BYTES
        if batch and (full or len(batch) == BATCH_EPISODES):
            yield batch
            batch, steps, size = [], 0, 0
        batch.append(episode.episode_id)
        steps, size = steps + episode.steps, size + episode.text_bytes
    if batch:
        yield batch


def _by_episode(rows: list[dict[str, Any]]) -> dict[str, list[dict[str, Any]]]:
    """Rows sorted by episode (as the analytics return them) grouped by episode id."""
    return {key: list(group) for key, group in groupby(rows, key=lambda r: r["episode_id"])}


def _listed(wanted: Sequence[str], known: Sequence[str], what: str, where: str) -> None:
    """Refuse ids of `wanted` not in `known` (`what`: `run`), naming the nearest to the first."""
    unknown = sorted(set(wanted) - set(known))
    if unknown:
        shown = ", ".join(repr(u) for u in unknown[:5]) + (" ..." if len(unknown) > 5 else "")
        hint = nearest_hint(unknown[0], sorted(set(known)), what)
        raise UnknownRunError(f"unknown {what}(s) {shown} in {where}{hint}")


def open_source(
    out: str | Path,
    *,
    runs: Sequence[str] | None = None,
    episodes: Sequence[str] | None = None,
    metrics_dir: str | Path | None = None,
) -> Source:
    """OUT opened for export: the runs named (default: every run), each with the episodes
    named (default: all of them). An OUT without a manifest, a run or an episode id that is
    not there raise one-line errors."""
    shown = str(out)
    if replay.read_manifest(out) is None:
        raise OutputDirError(
            f"{shown}: no manifest.json, not a replay output directory; run "
            f"`vge replay RUN... --bench BENCH --out {shown}` first"
        )
    table = store.runs(out)
    known = table["run_id"].to_list()
    if runs is not None:
        _listed(runs, known, "run", shown)
    chosen = [r for r in table.to_dicts() if runs is None or r["run_id"] in set(runs)]
    run_ids = [r["run_id"] for r in chosen]
    wanted = set(episodes) if episodes is not None else None
    every = {r: _contents(out, r) for r in run_ids}
    contents = {
        r: [c for c in listed if wanted is None or c.episode_id in wanted]
        for r, listed in every.items()
    }
    if episodes is not None:
        found = [c.episode_id for listed in every.values() for c in listed]
        _listed(episodes, found, "episode", f"the selected runs of {shown}")
        # the runs that hold none of the episodes named are left out
        chosen = [r for r in chosen if contents[r["run_id"]]]
        run_ids = [r["run_id"] for r in chosen]
    metrics = _metrics(out, run_ids, episodes, metrics_dir)
    columns = store.table_columns(out)[STEPS_TABLE]
    return Source(
        out=shown,
        runs=[
            Run(
                run_id=r["run_id"],
                model=r["model"],
                agent_kind=r["agent_kind"],
                lam=float(r["lambda"]),
                meta=json.loads(r["meta"] or "{}"),
                engine_version=r["engine_version"],
                bench=store.bench_dir(out, r["run_id"]),
                episodes=tuple(contents[r["run_id"]]),
                metrics=metrics.get(r["run_id"], {}),
            )
            for r in chosen
        ],
        step_columns=STEP_COLUMNS + tuple(c for c in STEP_METRICS if c in columns),
    )


def _metrics(
    out: str | Path,
    run_ids: list[str],
    episodes: Sequence[str] | None,
    metrics_dir: str | Path | None,
) -> dict[str, dict[str, float | None]]:
    """{run_id: {metric: value}} over the exported episodes (the registry's metrics)."""
    where: dict[str, Any] = {"run_id": run_ids}
    if episodes is not None:
        where["episode_id"] = list(episodes)
    df = computed_metrics(out, by=("run_id",), where=where, metrics_dir=metrics_dir)
    return {row.pop("run_id"): row for row in df.to_dicts()}


CONTENTS = """
SELECT e.episode_id, e.n_steps,
       coalesce(sum(strlen(coalesce(s.output, s.action_raw)) + strlen(coalesce(s.feedback_text, ''))), 0),
       min(s.timestamp), max(s.timestamp)
FROM episodes AS e
LEFT JOIN steps AS s ON s.run_id = e.run_id AND s.episode_id = e.episode_id
WHERE e.run_id = ?
GROUP BY e.episode_id, e.n_steps
ORDER BY e.episode_id
"""
"""Per episode of a run: its steps, the bytes of its responses and feedback, and its first
and last recorded times (one row per episode; the text is measured, not fetched)."""


def _contents(out: str | Path, run_id: str) -> list[Contents]:
    cursor = store.open_store(out).cursor()
    try:
        return [Contents(*row) for row in cursor.execute(CONTENTS, [run_id]).fetchall()]
    finally:
        cursor.close()


EPOCH = "1970-01-01T00:00:00+00:00"
"""What a required time says when nothing was recorded."""


def iso_time(seconds: float | None) -> str | None:
    """A recorded time (seconds since the epoch) in ISO 8601, UTC, to the millisecond (the
    precision the harnesses record); None when there is none."""
    if seconds is None or not math.isfinite(seconds):
        return None
    return datetime.fromtimestamp(seconds, tz=UTC).isoformat(timespec="milliseconds")


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


__all__ = [
    "BATCH_EPISODES",
    "BATCH_BYTES",
    "BATCH_STEPS",
    "Contents",
    "EPOCH",
    "RUN_COLUMNS",
    "STEP_COLUMNS",
    "STEP_METRICS",
    "STEP_VERDICT",
    "Episode",
    "Run",
    "Source",
    "episode_verdict",
    "iso_time",
    "open_source",
    "step_usage",
    "step_verdict",
]
