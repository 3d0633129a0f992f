"""The batch, the unit of work of `vge replay`: a run's lines with the context of their run
(`BatchTask`, `RunContext`), the one function that replays them and writes their parts
(`replay_batch`), and what it reports back (`BatchReport`, `BatchFailure`).

The runner calls `replay_batch` in this process (`workers=1`), in worker processes, or in
Ray tasks: the task and the report are plain picklable data, the function reads only its
task and its process's caches (`_worker.WorkerState`: the benchmark opened once, episode
setups and MCAP inputs, all bounded) and writes only files named by its task, so the output
cannot depend on where or how often it ran.
"""

from __future__ import annotations

import gc
import os
import socket
import traceback
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, NamedTuple

import msgspec
from pyarrow._compute import call_function

from .._errors import OutputError, TaskError, VGEError
from ..kernel import BatchTables, EpisodeInput, replay_kernel
from ..semantics import (
    NO_PRICES,
    EpisodeResult,
    EpisodeRow,
    GoalRow,
    Machine,
    Prices,
    StepRow,
    episode_lambda,
    replay_episode,
    rows_to_table,
)
from ._file_names import mcap_file_name, part_name
from ._files import write_part
from ._fs import location
from ._images import ViewImage
from ._layout import MCAP_DIR, TASKS
from ._load import decode_episode_line, episode_log
from ._quarantine import classify_decode_error, one_line
from ._rows import TABLE_ROWS
from ._worker import Ready, WorkerState, worker_state

if TYPE_CHECKING:
    from ._images import ImageSource

KERNEL = os.environ.get("VGE_REPLAY_ENGINE", "kernel") != "reference"
"""Replay with the compiled kernel (default) or, with `VGE_REPLAY_ENGINE=reference`,
episode by episode with `replay_episode` (the readable reference; same files, slower)."""


@dataclass(frozen=True)
class RunContext:
    """What a batch needs to know about its run (the same for every batch of the run)."""

    run_id: str
    model: str
    agent_kind: str
    run_lambda: float | None
    option_lambda: float | None
    file: str  # the episodes file, as given (quarantine records name it)
    staging: str  # the run's staging directory: <table>/part-NNNNN.parquet, mcap/
    row_group_rows: int
    mcap: bool = False
    mcap_episodes: frozenset[str] | None = None
    image_source: ImageSource | None = None
    prices: Prices = NO_PRICES  # the run's, for the cost columns (PROTOCOL §1.4)

    def wants_mcap(self, episode_id: str) -> bool:
        return self.mcap and (self.mcap_episodes is None or episode_id in self.mcap_episodes)


@dataclass(frozen=True)
class BatchTask:
    """Lines `lines` (numbered from 1 in their file, blank ones left out) of one run, batch
    number `index` of that run. `skip` holds lines the main process found to repeat an
    earlier episode: they are not replayed (see `RunJob.take`)."""

    ctx: RunContext
    bench: str
    index: int
    lines: tuple[tuple[int, bytes], ...]
    skip: frozenset[int] = frozenset()

    def skipping(self, lines: frozenset[int]) -> BatchTask:
        return replace(self, skip=lines)


class LineOutcome(NamedTuple):
    """A line not replayed: quarantined (`kind`, `reason`), or `skipped`."""

    line: int
    episode_id: str | None
    kind: str
    reason: str | None


SKIPPED = "skipped"
"""Outcome kind of a line in `BatchTask.skip` (the main process records why)."""


@dataclass
class BatchCounts:
    """Counts of the rows a batch wrote (the manifest's per-run counts add them up)."""

    steps: int = 0
    truncated: int = 0
    diverged: int = 0
    compared: int = 0
    episodes_diverged: int = 0
    goals: int = 0
    mcap_files: int = 0  # counted by the main process as it publishes them
    by_field: dict[str, int] = field(default_factory=dict)

    def add(self, other: BatchCounts) -> None:
        for name in ("steps", "truncated", "diverged", "compared", "episodes_diverged", "goals"):
            setattr(self, name, getattr(self, name) + getattr(other, name))
        for key, value in other.by_field.items():
            self.by_field[key] = self.by_field.get(key, 0) + value


@dataclass
class BatchReport:
    """What a replayed batch did: its lines' outcomes, the part files it wrote (table ->
    rows; no file when a table has no row), its counts, and where it ran.

    The outcomes are a few lists, not a record per line: every line not in `others` was
    replayed, and most lines are. Records for a batch's 4,096 lines took 3 ms to pickle in
    the worker and 5 ms to unpickle and go through in the main process, which takes every
    report: ten times what these lists take."""

    index: int
    lines: int  # the lines of the batch
    episode_ids: list[str]  # of its well-formed episode records, in line order
    episode_lines: list[int]  # their line numbers (the main process's duplicate check)
    others: list[LineOutcome]  # the lines not replayed, in line order
    devices: list[str]  # of the episodes found in the tasks (the run's inputs list them)
    mcap: dict[int, tuple[str, str]]  # replayed line -> episode id, file in staging mcap/
    parts: dict[str, int]
    counts: BatchCounts
    node: str = ""


@dataclass(frozen=True)
class BatchFailure:
    """An unexpected error inside a batch, carried back as plain data."""

    index: int
    line: int | None
    message: str
    details: str
    node: str = ""
    output: str | None = None
    """The output file that could not be written (a full disk): the error names it."""


def replay_batch(task: BatchTask) -> BatchReport | BatchFailure:
    """Replay a batch and write its parts; every error comes back as data."""
    try:
        return _replay(worker_state(task.bench), task)
    except OutputError as exc:  # a full disk: the output file is to blame, not the line
        details = traceback.format_exc()
        return BatchFailure(task.index, None, exc.message, details, socket.gethostname(), exc.path)
    except Exception as exc:  # a bug or an I/O error: fatal, reported by the main process
        return BatchFailure(
            task.index,
            getattr(exc, "vge_line", None),
            one_line(f"replay failed: {type(exc).__name__}: {exc}"),
            traceback.format_exc(),
            socket.gethostname(),
        )


@dataclass
class _Lines:
    """A batch's lines, decoded and checked: the episodes to replay and their line numbers,
    and what its report says of the lines (`BatchReport`)."""

    episodes: list[EpisodeInput] = field(default_factory=list)
    numbers: list[int] = field(default_factory=list)
    ids: list[str] = field(default_factory=list)
    id_lines: list[int] = field(default_factory=list)
    others: list[LineOutcome] = field(default_factory=list)
    devices: set[str] = field(default_factory=set)


def _replay(state: WorkerState, task: BatchTask) -> BatchReport:
    """Decode and check each line, replay the replayable ones together, write the parts
    (and the MCAP files, from the same rows).

    The cyclic garbage collector is paused for the batch: what it builds is acyclic, and
    the collector's scans of the growing batch would cost a large share of the time. What
    outlives the batch (compiled machines, plans, kernel tables: caches that only grow) is
    then frozen, so later collections do not scan it again and again (a tenth of the time
    of a replay otherwise)."""
    ctx = task.ctx
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        lines = _prepare_lines(state, task)
        tables, results = _replay_episodes(task, lines)
        mcap = _write_mcaps(state, ctx, lines, tables, results) if ctx.mcap else {}
        lines.devices.update({e.task.device_id for e in lines.episodes})
        return BatchReport(
            task.index,
            len(task.lines),
            lines.ids,
            lines.id_lines,
            lines.others,
            sorted(lines.devices),
            mcap,
            _write_parts(task, tables),
            _counts(tables),
            socket.gethostname(),
        )
    finally:
        if was_enabled:
            gc.freeze()
            gc.enable()


def _prepare_lines(state: WorkerState, task: BatchTask) -> _Lines:
    """Each line decoded and checked: an episode to replay, or the outcome of a line not
    replayed. The line of an episode ready in this process (`WorkerState.ready`: its checks
    passed at an earlier line) is not checked again: the look-ups of the checks were about
    half of what preparing a line cost beyond its decoding."""
    ctx, got, ready = task.ctx, _Lines(), state.ready
    number = None
    try:
        for number, raw in task.lines:
            if number in task.skip:
                got.others.append(LineOutcome(number, None, SKIPPED, None))
                continue
            try:
                log = decode_episode_line(raw)
            except msgspec.DecodeError as exc:
                kind, reason, episode_id = classify_decode_error(raw, exc)
                got.others.append(LineOutcome(number, episode_id, kind, reason))
                continue
            eid = log.episode_id
            got.ids.append(eid)
            got.id_lines.append(number)
            r = ready.get(eid) or _checked_episode(state, number, eid, got)
            if r is not None:
                machine, t, setup = r
                lam = episode_lambda(t, ctx.run_lambda, ctx.option_lambda)
                got.episodes.append(EpisodeInput(machine, t, setup, log, lam))
                got.numbers.append(number)
    except Exception as exc:
        exc.vge_line = number  # type: ignore[attr-defined]
        raise
    return got


def _replay_episodes(
    task: BatchTask, lines: _Lines
) -> tuple[BatchTables, dict[int, EpisodeResult]]:
    """The batch's tables, from the kernel (or the reference with `VGE_REPLAY_ENGINE`), and
    the reference's results by episode when the reference replayed them."""
    ctx = task.ctx
    todo = zip(lines.numbers, lines.episodes, strict=True)
    if not KERNEL:
        results = {j: _replay_reference(ctx, n, e) for j, (n, e) in enumerate(todo)}
        return reference_tables([results[j] for j in range(len(results))]), results
    try:
        tables = replay_kernel(
            lines.episodes,
            run_id=ctx.run_id,
            model=ctx.model,
            agent_kind=ctx.agent_kind,
            prices=ctx.prices,
        )
    except Exception as exc:
        for number, e in todo:  # an episode at fault raises, naming its line
            _replay_reference(ctx, number, e)
        exc.vge_line = task.lines[0][0] if task.lines else None  # type: ignore[attr-defined]
        raise
    return tables, {}


MCAP_ROWS_AT_ONCE = 256
"""Episodes whose rows are read back from the tables together for their MCAP files: bounds
the Python objects held at once, whatever the size of the batch."""


def _write_mcaps(
    state: WorkerState,
    ctx: RunContext,
    lines: _Lines,
    tables: BatchTables,
    results: dict[int, EpisodeResult],
) -> dict[int, tuple[str, str]]:
    """The MCAP file of each episode that wants one, written from the rows of the replay
    that made the tables (no second replay): line -> episode id, its temporary file name."""
    episodes = lines.episodes
    wanted = [j for j, e in enumerate(episodes) if ctx.wants_mcap(e.task.episode_id)]
    mcap = {}
    for start in range(0, len(wanted), MCAP_ROWS_AT_ONCE):
        chunk = wanted[start : start + MCAP_ROWS_AT_ONCE]
        missing = [j for j in chunk if j not in results]
        read_back = dict(zip(missing, tables.episode_results(missing), strict=True))
        for j in chunk:
            number, e = lines.numbers[j], episodes[j]
            result = results[j] if j in results else read_back[j]
            mcap_tmp = _write_mcap(state, ctx, number, e.machine, result)
            mcap[number] = (e.task.episode_id, mcap_tmp)
    return mcap


def _write_parts(task: BatchTask, tables: BatchTables) -> dict[str, int]:
    """One Parquet part per table with rows (table name -> rows)."""
    parts = {}
    for name, table in zip(TABLE_ROWS, tables[:3], strict=True):
        parts[name] = table.num_rows
        path = location(task.ctx.staging) / name / part_name(task.index)
        if table.num_rows:
            write_part(table, path, task.ctx.row_group_rows)
        else:
            path.unlink(missing_ok=True)  # a redone batch may have lost its last rows
    return parts


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
    """The batch's counts, by Arrow's compute functions called by name: `pyarrow.compute`,
    which wraps them, builds its wrappers and their docs on import (0.03 s in every process
    that replays, a worker's included), for the four functions used here."""
    steps, episodes = tables.steps, tables.episodes
    counts = BatchCounts(steps=steps.num_rows, goals=tables.goals.num_rows)
    if steps.num_rows:
        counts.truncated = call_function("sum", [steps["truncated"]]).as_py() or 0
        diverged = steps["diverged"]
        counts.compared = len(diverged) - diverged.null_count
        counts.diverged = call_function("sum", [diverged]).as_py() or 0
        flat = call_function("list_flatten", [steps["diverged_fields"]])
        if len(flat):
            for item in call_function("value_counts", [flat]).to_pylist():
                counts.by_field[item["values"]] = item["counts"]
    if episodes.num_rows:
        # Episodes with a diverged step: the sum of the signs of counts (a comparison with 0
        # would make 0 an Arrow scalar, which imports pandas in a worker that needs none).
        signs = call_function("sign", [episodes["diverged_steps"]])
        counts.episodes_diverged = call_function("sum", [signs]).as_py() or 0
    return counts


def _replay_reference(ctx: RunContext, number: int, e: EpisodeInput) -> EpisodeResult:
    try:
        return replay_episode(
            e.machine,
            e.task,
            episode_log(e.log),
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
    from ._mcap import write_episode_mcap  # its libraries (0.03-0.1 s) load only with --mcap

    mcap_tmp = f"{mcap_file_name(result.episode.episode_id)}.L{number}.tmp"
    source = ctx.image_source

    def image(view: str, m: Machine = machine) -> ViewImage | None:
        return None if source is None else state.image(source, m, view)

    with (location(ctx.staging) / MCAP_DIR / mcap_tmp).writer(sync=False) as fh:
        write_episode_mcap(fh, machine, result, ssm_bytes=state.ssm(machine), image=image)
    return mcap_tmp


def _checked_episode(state: WorkerState, number: int, eid: str, got: _Lines) -> Ready | None:
    """The checks of an episode not ready in this process: its task, its device's SSM, its
    setup. Ready (and kept), or None with the line's quarantine outcome in `got`."""
    bench = state.bench
    entry = bench.tasks.get(eid)
    if entry is None:
        reason = f"episode {eid!r} is not in {bench.tasks_path.name}"
        got.others.append(LineOutcome(number, eid, "unknown_episode", reason))
        return None
    task = entry.task
    device = task.device_id
    got.devices.add(device)
    missing = bench.no_machine(device)
    if missing is not None:
        reason = one_line(f"device {device!r} ({TASKS} line {entry.line}) {missing}")
        got.others.append(LineOutcome(number, eid, "unknown_device", reason))
        return None
    try:
        machine = bench.machine(device)
    except VGEError as exc:
        reason = one_line(f"SSM of device {device!r} does not load: {exc}")
        got.others.append(LineOutcome(number, eid, "invalid_ssm", reason))
        return None
    try:
        setup = state.setup(machine, task)
    except TaskError as exc:
        reason = one_line(f"{exc} ({TASKS} line {entry.line})")
        got.others.append(LineOutcome(number, eid, "task_error", reason))
        return None
    ready = Ready(machine, task, setup)
    state.remember_ready(ready)
    return ready
