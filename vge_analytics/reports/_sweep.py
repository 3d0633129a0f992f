"""Budget sweeps: SR and SSR per run at several lambdas, by re-replaying the logs in memory.

The inputs come from `OUT/manifest.json` (each run's directory, episodes file and benchmark,
as given to `vge replay`); their sha256 must still match the manifest (a changed log, task
file or SSM would make the sweep disagree with OUT, so it is refused). Every episode that OUT
holds for a run is replayed again at each lambda by `replay.io.replay_lambdas`, in batches of
lines run by the executors of `vge replay` (this process, worker processes, or a Ray
cluster), and the metrics are computed from the resulting episode rows with the registry's
own SQL.

Which lambdas the logs support
------------------------------
A log was produced under a budget: the harness stopped the agent when its budget (at the
*recorded* lambda: the task's `lambda`, else the run's, else 5, the precedence of
`vge replay` without `--lambda`) ran out. Replaying with a *smaller* lambda is always
possible: the budgets run out earlier and the rest of the log is truncated. Replaying with a
*larger* lambda needs steps the agent may never have been allowed to take. An episode
supports a lambda L above its recorded lambda when the log holds every step the larger budget
would have allowed, which is the case exactly when

- its replay at L does not end with `log_ended` (it reached success or the L budget within
  the logged steps: the log, e.g. with steps logged after the recorded budget, went far
  enough), or
- its replay at the recorded lambda already ended with `log_ended`: the log stopped before
  its budget ran out (the agent or harness ended the episode for another reason), so a larger
  budget would not have produced more steps either. (Success at the recorded lambda is
  covered by the first case: budgets only grow with lambda, so it succeeds at L too.)

An episode that hit its budget at the recorded lambda (`budget_global` / `budget_local`) and
whose log has nothing beyond the steps that budget allowed would end with `log_ended` at L:
such a lambda is refused for its run, with a one-line message naming the run, the lambda and
the episode.
"""

from __future__ import annotations

import contextlib
import hashlib
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import polars as pl
import pyarrow as pa

import replay
from replay.io import (
    EPISODES_TABLE,
    RUNS_TABLE,
    manifest_path,
)

from .._errors import ConfigError, SweepInputError, SweepRefused
from ..metrics import Metric, MetricSet, MetricsSource, metric_set
from ..metrics import metrics as computed_metrics
from ..store import Store, check_runs, memory_store, open_store, resolve_input, run_query
from ._defaults import DEFAULT_SWEEP_METRICS


def parse_lambdas(value: str | Sequence[float]) -> list[float]:
    """Sorted distinct positive lambdas from '2,3,4,5' or a sequence of numbers."""
    items: Sequence[object]
    items = [v.strip() for v in value.split(",") if v.strip()] if isinstance(value, str) else value
    out: set[float] = set()
    for item in items:
        try:
            lam = float(item)  # type: ignore[arg-type]
        except (TypeError, ValueError):
            raise ConfigError(f"lambda {item!r} is not a number") from None
        if not math.isfinite(lam) or lam <= 0:
            raise ConfigError(f"lambda must be a positive number, not {item!r}")
        out.add(lam)
    if not out:
        raise ConfigError("no lambda given (e.g. --lambdas 2,3,4,5)")
    return sorted(out)


@dataclass(frozen=True)
class _RunJob:
    run_id: str
    model: str
    agent_kind: str
    run_lambda: float | None
    episodes_file: str
    bench: str
    episode_ids: frozenset[str]
    lambdas: tuple[float, ...]

    def tasks(self) -> Iterator[replay.io.LambdaTask]:
        """The run's lines in batches of BATCH_LINES."""
        lines: list[tuple[int, bytes]] = []
        index = 0
        for item in replay.io.iter_lines(self.episodes_file):
            lines.append(item)
            if len(lines) == BATCH_LINES:
                yield self._task(index, lines)
                lines, index = [], index + 1
        if lines:
            yield self._task(index, lines)

    def _task(self, index: int, lines: list[tuple[int, bytes]]) -> replay.io.LambdaTask:
        return replay.io.LambdaTask(
            run_id=self.run_id,
            model=self.model,
            agent_kind=self.agent_kind,
            run_lambda=self.run_lambda,
            bench=self.bench,
            index=index,
            lines=tuple(lines),
            episode_ids=self.episode_ids,
            lambdas=self.lambdas,
        )


BATCH_LINES = 1024
"""Episode lines per sweep task."""


def _resolve(
    out: Path | replay.Location, path: str, what: str, run_id: str
) -> Path | replay.Location:
    p = resolve_input(out, path)
    if p.exists():
        return p
    raise SweepInputError(
        f"run {run_id}: {what} {path} recorded in manifest.json not found "
        "(paths are kept as given to `vge replay`: run `vge sweep` from the directory the "
        "replay ran in, or next to OUT)"
    )


def _sha256(path: Path | replay.Location) -> str:
    h = hashlib.sha256()
    with replay.location(path).open_read() as fh:
        while chunk := fh.read(1 << 20):
            h.update(chunk)
    return h.hexdigest()


def _check_unchanged(out: Path | replay.Location, entry, run_id: str) -> None:
    """The inputs must be the ones OUT was replayed from (sha256 in the manifest)."""
    refs = [("episodes file", entry.inputs.episodes), ("tasks file", entry.inputs.tasks)]
    refs += [(f"SSM of {device}", ref) for device, ref in sorted(entry.inputs.ssm.items())]
    for what, ref in refs:
        path = _resolve(out, ref.path, what, run_id)
        if ref.sha256 is not None and _sha256(path) != ref.sha256:
            raise SweepInputError(
                f"run {run_id}: {what} {ref.path} changed since OUT was replayed "
                "(sha256 differs from manifest.json); re-run `vge replay` first"
            )


def _jobs(store: Store, run_ids: Sequence[str] | None, lambdas: list[float]) -> list[_RunJob]:
    manifest = replay.read_manifest(store.out)
    if manifest is None:
        raise SweepInputError(f"{manifest_path(store.out)}: not found; the sweep needs it")
    entries = {e.run_id: e for e in manifest.runs}
    known = check_runs(store, run_ids or [])
    wanted = list(run_ids) if run_ids else known
    for run in wanted:
        if run not in entries:
            raise SweepInputError(f"run {run}: not in {manifest_path(store.out)}")
    eps = run_query(
        store,
        "SELECT run_id, episode_id FROM episodes WHERE run_id IN "
        "(SELECT unnest(CAST(? AS VARCHAR[])))",
        [wanted],
    )
    jobs = []
    for run in wanted:
        e = entries[run]
        _check_unchanged(store.out, e, run)
        episodes_file = _resolve(store.out, e.inputs.episodes.path, "episodes file", run)
        bench = _resolve(store.out, e.inputs.bench, "benchmark directory", run)
        ids = frozenset(eps.filter(pl.col("run_id") == run)["episode_id"].to_list())
        jobs.append(
            _RunJob(
                run_id=run,
                model=e.run.model,
                agent_kind=e.run.agent_kind,
                run_lambda=e.run.lam,
                episodes_file=str(episodes_file),
                bench=str(bench),
                episode_ids=ids,
                lambdas=tuple(lambdas),
            )
        )
    return jobs


def _replay(jobs: list[_RunJob], executor) -> pa.Table:
    """Episode rows of every run at every lambda, in line order (the first occurrence of an
    episode counts); the first refusal, in run and line order, ends the sweep."""

    def items() -> Iterator[tuple[_RunJob, replay.io.LambdaTask]]:
        for job in jobs:
            for task in job.tasks():
                yield job, task

    tables: list[pa.Table] = []
    seen: dict[str, set[str]] = {job.run_id: set() for job in jobs}
    ahead = 2 * executor.slots
    for job, _, batch in replay.io.in_order(executor, replay.io.replay_lambdas, items(), ahead):
        keep: list[bool] = []
        for eid, refusal in zip(batch.episode_ids, batch.refusals, strict=True):
            first = eid not in seen[job.run_id]
            if first and refusal is not None:
                raise SweepRefused(refusal)
            seen[job.run_id].add(eid)
            keep.extend([first] * len(job.lambdas))
        tables.append(batch.episodes.filter(pa.array(keep, pa.bool_())))
    schema = replay.arrow_schema(replay.EpisodeRow)
    return pa.concat_tables(tables) if tables else schema.empty_table()


SWEEP_BY: tuple[str, ...] = ("run_id", "model", "lambda")
"""The groups of a sweep: a run at a lambda."""


def _metrics_of(
    store: Store, episodes: pa.Table, chosen: list[Metric], available: MetricSet
) -> pl.DataFrame:
    """Metrics per (run_id, model, lambda) over in-memory episode rows: the registry's SQL on
    a store of their own (`memory_store`), guarded and limited as a query over OUT is, and
    named in messages by OUT."""
    runs = episodes.select(["run_id", "model", "agent_kind", "lambda"])
    runs = runs.group_by(runs.column_names).aggregate([])  # a run at each lambda, once
    tables = {EPISODES_TABLE: episodes, RUNS_TABLE: runs}
    with contextlib.closing(memory_store(tables, label=store.out, limits=store.limits)) as held:
        return computed_metrics(held, by=SWEEP_BY, metrics=[m.name for m in chosen], metrics_dir=available)


def sweep(
    out,
    lambdas: str | Sequence[float] = (2, 3, 4, 5),
    *,
    runs: Sequence[str] | None = None,
    metrics: str | Sequence[str] | None = None,
    workers: int = 1,
    ray: str | None = None,
    metrics_dir: MetricsSource = None,
) -> pl.DataFrame:
    """SR and SSR (or other episode metrics) per run and lambda, by re-replaying the logs.

    Columns: run_id, model, lambda, then per metric M: M, `M_gain` (M minus M at the smallest
    lambda of the sweep, in the metric's unit: percentage points for rates) and `M_rel_gain`
    (that gain relative to M at the smallest lambda, in percent; null when that is 0 or null).
    Rows sorted by run_id, lambda. Raises `SweepRefused` when a lambda is above what a run's
    logs support (see the module docstring). `workers` processes replay the batches, or the
    Ray cluster at `ray` (as `vge replay --ray`); the result does not depend on them.
    `metrics_dir`: the metrics folder whose definitions are used (default
    `$VGE_METRICS_DIR`, else the built-ins).
    """
    store = open_store(out)
    lams = parse_lambdas(lambdas)
    available = metric_set(metrics_dir)
    chosen = available.resolve(list(metrics) if metrics else list(DEFAULT_SWEEP_METRICS))
    not_episode = [m.name for m in chosen if m.grain != EPISODES_TABLE]
    if not_episode:
        usable = ", ".join(m.name for m in available if m.grain == EPISODES_TABLE)
        raise ConfigError(
            f"the sweep computes metrics from episode rows only; {', '.join(not_episode)} "
            f"need steps or goals (episode metrics: {usable})"
        )
    jobs = _jobs(store, runs, lams)
    executor = replay.io.make_executor(workers, ray)
    try:
        episodes = _replay(jobs, executor)
    finally:
        executor.close()
    names = [m.name for m in chosen]
    df = _metrics_of(store, episodes, chosen, available)
    base = df.sort("lambda").group_by("run_id", maintain_order=True).first()
    base = base.select("run_id", *[pl.col(n).alias(f"__base_{n}") for n in names])
    df = df.join(base, on="run_id", how="left")
    gains = []
    for n in names:
        b = pl.col(f"__base_{n}")
        gains.append((pl.col(n) - b).alias(f"{n}_gain"))
        gains.append(
            pl.when(b.is_not_null() & (b != 0))
            .then(100.0 * (pl.col(n) - b) / b)
            .otherwise(None)
            .alias(f"{n}_rel_gain")
        )
    df = df.with_columns(gains)
    order = ["run_id", "model", "lambda"]
    for n in names:
        order += [n, f"{n}_gain", f"{n}_rel_gain"]
    return df.select(order).sort("run_id", "lambda")


__all__ = ["SWEEP_BY", "parse_lambdas", "sweep"]
