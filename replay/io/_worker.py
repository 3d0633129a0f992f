"""`replay_batch`: the one function that replays a batch of lines and writes its parts.

The runner calls it in this process (`workers=1`), in worker processes, or in Ray tasks:
it reads only its task and a per-process cache (the benchmark opened once, episode setups
and MCAP inputs, all bounded), and writes only files named by its task, so the output
cannot depend on where or how often it ran.
"""

from __future__ import annotations

import gc
import os
import socket
import traceback
from dataclasses import dataclass, field

import msgspec
import pyarrow.compute as pc

from .._errors import TaskError, VGEError
from ..kernel._batch import BatchTables, EpisodeInput, replay_kernel
from ..semantics._budget import episode_lambda
from ..semantics._episode import EpisodeResult, EpisodeSetup, replay_episode, setup_episode
from ..semantics._machine import Machine
from ..semantics._records import Task
from ..semantics._rows import EpisodeRow, GoalRow, StepRow
from ..semantics._tables import rows_to_table
from ._decode import decode
from ._files import write_part
from ._fs import location
from ._images import ImageSource, ViewImage, as_view_image
from ._layout import MCAP_DIR, SSM_DIR, SSM_SUFFIX, TABLE_ROWS, TASKS
from ._load import Benchmark, episode_decoder
from ._mcap import attached_ssm, mcap_file_name, write_episode_mcap
from ._quarantine import classify_decode_error, one_line
from ._task import (
    SKIPPED,
    BatchCounts,
    BatchFailure,
    BatchReport,
    BatchTask,
    LineOutcome,
    RunContext,
    part_name,
)

KERNEL = os.environ.get("VGE_REPLAY_ENGINE", "kernel") != "reference"
"""Replay with the compiled kernel (default) or, with `VGE_REPLAY_ENGINE=reference`,
episode by episode with `replay_episode` (the readable reference; same files, slower)."""

SETUP_CACHE_SIZE = 50_000
"""Episode setups (plans) kept per process; bounds memory whatever the number of tasks."""
_IMAGE_CACHE_SIZE = 128
_SSM_CACHE_SIZE = 256
_BENCHES = 4


def _remember(cache: dict, key: object, value: object, limit: int) -> None:
    """Insert into a bounded cache, dropping the oldest entry when full."""
    if len(cache) >= limit:
        del cache[next(iter(cache))]
    cache[key] = value


@dataclass
class WorkerState:
    """Per-process caches (bounded): the benchmark, episode setups, SSM bytes, view images."""

    bench: Benchmark
    setups: dict[str, EpisodeSetup | TaskError] = field(default_factory=dict)
    ssm_bytes: dict[str, bytes] = field(default_factory=dict)
    images: dict[tuple[str, str], ViewImage | None] = field(default_factory=dict)

    def setup(self, machine: Machine, task: Task) -> EpisodeSetup:
        got = self.setups.get(task.episode_id)
        if got is None:
            try:
                got = setup_episode(machine, task)
            except TaskError as exc:
                got = exc
            _remember(self.setups, task.episode_id, got, SETUP_CACHE_SIZE)
        if isinstance(got, TaskError):
            raise got
        return got

    def image(self, source: ImageSource, machine: Machine, view: str) -> ViewImage | None:
        key = (machine.device_id, view)
        if key not in self.images:
            _remember(self.images, key, as_view_image(source(machine, view)), _IMAGE_CACHE_SIZE)
        return self.images[key]

    def ssm(self, machine: Machine) -> bytes:
        got = self.ssm_bytes.get(machine.device_id)
        if got is None:
            got = attached_ssm(machine)
            _remember(self.ssm_bytes, machine.device_id, got, _SSM_CACHE_SIZE)
        return got


_states: dict[str, WorkerState] = {}


def worker_state(bench: str) -> WorkerState:
    """This process's state for a benchmark directory (opened once)."""
    got = _states.get(bench)
    if got is None:
        got = WorkerState(Benchmark.open(bench))
        _remember(_states, bench, got, _BENCHES)
    return got


def adopt(state: WorkerState, bench: str) -> None:
    """Use an already opened benchmark for `bench` in this process (the runner's own)."""
    _remember(_states, bench, state, _BENCHES)


def replay_batch(task: BatchTask) -> BatchReport | BatchFailure:
    """Replay a batch and write its parts; every error comes back as data."""
    try:
        return _replay(worker_state(task.bench), task)
    except Exception as exc:  # a bug or an I/O error: fatal, reported by the main process
        return BatchFailure(
            task.index,
            getattr(exc, "vge_line", None),
            one_line(f"replay failed: {type(exc).__name__}: {exc}"),
            traceback.format_exc(),
            socket.gethostname(),
        )


def _replay(state: WorkerState, task: BatchTask) -> BatchReport:
    """Decode and check each line, replay the replayable ones together, write the parts.

    The cyclic garbage collector is paused for the batch: what it builds is acyclic, and
    the collector's scans of the growing batch would cost a large share of the time. What
    outlives the batch (compiled machines, plans, kernel tables: caches that only grow) is
    then frozen, so later collections do not scan it again and again (a tenth of the time
    of a replay otherwise)."""
    ctx = task.ctx
    outcomes: list[LineOutcome | None] = []
    todo: list[tuple[int, int, EpisodeInput]] = []  # (outcome index, line number, episode)
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        for number, raw in task.lines:
            if number in task.skip:
                outcomes.append(LineOutcome(number, None, False, SKIPPED, None))
                continue
            try:
                _prepare_line(state, ctx, number, raw, outcomes, todo)
            except Exception as exc:
                exc.vge_line = number  # type: ignore[attr-defined]
                raise
        episodes = [e for _, _, e in todo]
        scalar: dict[int, EpisodeResult] = {}
        if KERNEL:
            try:
                tables = replay_kernel(
                    episodes,
                    run_id=ctx.run_id,
                    model=ctx.model,
                    agent_kind=ctx.agent_kind,
                    prices=ctx.prices,
                )
            except Exception as exc:
                for _, number, e in todo:  # an episode at fault raises, naming its line
                    _replay_reference(ctx, number, e)
                exc.vge_line = task.lines[0][0] if task.lines else None  # type: ignore[attr-defined]
                raise
        else:
            scalar = {j: _replay_reference(ctx, n, e) for j, (_, n, e) in enumerate(todo)}
            tables = reference_tables([scalar[j] for j in range(len(todo))])
        counts = _counts(tables)
        for j, (at, number, e) in enumerate(todo):
            mcap_tmp = None
            if ctx.wants_mcap(e.task.episode_id):
                result = scalar.get(j) or _replay_reference(ctx, number, e)
                mcap_tmp = _write_mcap(state, ctx, number, e.machine, result)
            outcomes[at] = LineOutcome(
                number,
                e.task.episode_id,
                True,
                None,
                None,
                int(tables.step_counts[j]),
                int(tables.goal_counts[j]),
                mcap_tmp,
            )
        parts = {}
        for name, table in zip(TABLE_ROWS, tables[:3], strict=True):
            parts[name] = table.num_rows
            path = location(ctx.staging) / name / part_name(task.index)
            if table.num_rows:
                write_part(table, path, ctx.row_group_rows)
            else:
                path.unlink(missing_ok=True)  # a redone batch may have lost its last rows
        return BatchReport(
            task.index, [o for o in outcomes if o is not None], parts, counts, socket.gethostname()
        )
    finally:
        if was_enabled:
            gc.freeze()
            gc.enable()


def reference_tables(results: list[EpisodeResult]) -> BatchTables:
    """The tables of reference replays, as the kernel returns them."""
    return BatchTables(
        rows_to_table([t for r in results for t in r.step_tuples], StepRow),
        rows_to_table([r.episode for r in results], EpisodeRow),
        rows_to_table([g for r in results for g in r.goals], GoalRow),
        [len(r.step_tuples) for r in results],
        [len(r.goals) for r in results],
    )


def _counts(tables: BatchTables) -> BatchCounts:
    steps, episodes = tables.steps, tables.episodes
    counts = BatchCounts(steps=steps.num_rows, goals=tables.goals.num_rows)
    if steps.num_rows:
        counts.truncated = pc.sum(steps["truncated"]).as_py() or 0
        diverged = steps["diverged"]
        counts.compared = len(diverged) - diverged.null_count
        counts.diverged = pc.sum(diverged).as_py() or 0
        flat = pc.list_flatten(steps["diverged_fields"])
        if len(flat):
            for item in pc.value_counts(flat).to_pylist():
                counts.by_field[item["values"]] = item["counts"]
    if episodes.num_rows:
        counts.episodes_diverged = pc.sum(pc.greater(episodes["diverged_steps"], 0)).as_py() or 0
    return counts


def _replay_reference(ctx: RunContext, number: int, e: EpisodeInput) -> EpisodeResult:
    try:
        return replay_episode(
            e.machine,
            e.task,
            e.log,
            lam=e.lam,
            run_id=ctx.run_id,
            model=ctx.model,
            agent_kind=ctx.agent_kind,
            setup=e.setup,
            prices=ctx.prices,
        )
    except Exception as exc:
        exc.vge_line = number  # type: ignore[attr-defined]
        raise


def _write_mcap(
    state: WorkerState, ctx: RunContext, number: int, machine: Machine, result: EpisodeResult
) -> str:
    mcap_tmp = f"{mcap_file_name(result.episode.episode_id)}.L{number}.tmp"
    source = ctx.image_source

    def image(view: str, m: Machine = machine) -> ViewImage | None:
        return None if source is None else state.image(source, m, view)

    with (location(ctx.staging) / MCAP_DIR / mcap_tmp).writer(sync=False) as fh:
        write_episode_mcap(
            fh, machine, result, ssm_bytes=state.ssm(machine), image=image
        )
    return mcap_tmp


def _prepare_line(
    state: WorkerState,
    ctx: RunContext,
    number: int,
    raw: bytes,
    outcomes: list[LineOutcome | None],
    todo: list[tuple[int, int, EpisodeInput]],
) -> None:
    """Decode and check one line: a quarantine outcome, or an episode to replay (its
    outcome is filled in after the replay)."""
    bench = state.bench
    try:
        log = decode(episode_decoder, raw)
    except msgspec.DecodeError as exc:
        kind, reason, episode_id = classify_decode_error(raw, exc)
        outcomes.append(LineOutcome(number, episode_id, False, kind, reason))
        return
    eid = log.episode_id
    entry = bench.tasks.get(eid)
    if entry is None:
        reason = f"episode {eid!r} is not in {bench.tasks_path.name}"
        outcomes.append(LineOutcome(number, eid, True, "unknown_episode", reason))
        return
    task = entry.task
    device = task.device_id
    if device not in bench.ssm_paths:
        where = f"{SSM_DIR}/{device}{SSM_SUFFIX}"
        reason = f"device {device!r} ({TASKS} line {entry.line}) has no SSM file {where}"
        outcomes.append(LineOutcome(number, eid, True, "unknown_device", reason))
        return
    try:
        machine = bench.machine(device)
    except VGEError as exc:
        reason = one_line(f"SSM of device {device!r} does not load: {exc}")
        outcomes.append(LineOutcome(number, eid, True, "invalid_ssm", reason))
        return
    try:
        setup = state.setup(machine, task)
    except TaskError as exc:
        reason = one_line(f"{exc} ({TASKS} line {entry.line})")
        outcomes.append(LineOutcome(number, eid, True, "task_error", reason))
        return
    lam = episode_lambda(task, ctx.run_lambda, ctx.option_lambda)
    todo.append((len(outcomes), number, EpisodeInput(machine, task, setup, log, lam)))
    outcomes.append(None)


__all__ = ["WorkerState", "adopt", "replay_batch", "worker_state"]

