"""The worker side of `replay_runs`: one batch of episode lines -> rows and outcomes.

A batch is a fixed number of consecutive lines of one episodes file. The same function runs
in the main process (`workers=1`) and in worker processes, so the output cannot depend on
the number of workers. Each worker opens the benchmark once (machines compile lazily) and
caches the episode setup (planning) per task.

Duplicates are not decided here: only the main process sees every line of a run in order.
"""

from __future__ import annotations

import gc
import os
import re
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple
from urllib.parse import quote

import msgspec
import pyarrow as pa

from .._errors import TaskError, VGEError
from ..kernel._columnar import ColumnarBatch, EpisodeInput, replay_columnar
from ..kernel._columnar_tables import ColumnarCache
from ..semantics._episode import EpisodeResult, EpisodeSetup, replay_episode, setup_episode
from ..semantics._machine import Machine
from ..semantics._records import Task
from ..semantics._rows import EpisodeRow, GoalRow, StepRow
from ..semantics._tables import rows_to_table
from ..semantics._vocab import DEFAULT_LAMBDA
from ._load import Benchmark, episode_decoder
from ._mcap import ImageSource, ImageTuple, write_episode_mcap
from ._quarantine import classify_decode_error, one_line

_SAFE = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9._+@-]{0,199}$")


def safe_file_name(name: str) -> str:
    """A file name for an id: unchanged when harmless, else percent-encoded."""
    if _SAFE.match(name):
        return name
    encoded = quote(name, safe="")
    return "%2E" + encoded[1:] if encoded.startswith(".") else encoded


@dataclass(frozen=True)
class RunContext:
    """What a worker needs to know about the run a batch belongs to (picklable)."""

    run_id: str
    model: str
    agent_kind: str
    run_lambda: float | None
    option_lambda: float | None
    file: str
    mcap_dir: str | None = None
    mcap_episodes: frozenset[str] | None = None
    image_source: ImageSource | None = None
    library: str = ""

    def wants_mcap(self, episode_id: str) -> bool:
        return self.mcap_dir is not None and (
            self.mcap_episodes is None or episode_id in self.mcap_episodes
        )


class LineOutcome(NamedTuple):
    """What happened to one line: replayed (`kind` None) or quarantined."""

    line: int
    episode_id: str | None
    decoded: bool  # the line is a well-formed episode record (takes part in duplicates)
    kind: str | None
    reason: str | None
    n_steps: int = 0
    n_goals: int = 0
    mcap_tmp: str | None = None  # file name in the run's MCAP staging directory


@dataclass
class BatchResult:
    outcomes: list[LineOutcome]
    steps: pa.Table
    episodes: pa.Table
    goals: pa.Table


@dataclass(frozen=True)
class BatchFailure:
    """An unexpected error inside a batch, carried back as plain data."""

    line: int | None
    message: str
    details: str


COLUMNAR = os.environ.get("VGE_REPLAY_ENGINE", "columnar") != "scalar"
"""Replay batches with the columnar engine (default) or, with `VGE_REPLAY_ENGINE=scalar`,
episode by episode with `replay_episode` (the reference; same tables, slower)."""

SETUP_CACHE_SIZE = 50_000
"""Episode setups (plans) kept per process; bounds memory whatever the number of tasks."""
_IMAGE_CACHE_SIZE = 128
_SSM_CACHE_SIZE = 256


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
    images: dict[tuple[str, str], ImageTuple | None] = field(default_factory=dict)
    columnar: ColumnarCache | None = field(
        default_factory=lambda: ColumnarCache() if COLUMNAR else None
    )

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

    def image(self, source: ImageSource, machine: Machine, view: str) -> ImageTuple | None:
        key = (machine.device_id, view)
        if key not in self.images:
            _remember(self.images, key, as_image_tuple(source(machine, view)), _IMAGE_CACHE_SIZE)
        return self.images[key]

    def ssm(self, machine: Machine) -> bytes:
        got = self.ssm_bytes.get(machine.device_id)
        if got is None:
            try:
                got = Path(machine.source).read_bytes()
            except OSError:
                got = msgspec.json.encode(machine.ssm)
            _remember(self.ssm_bytes, machine.device_id, got, _SSM_CACHE_SIZE)
        return got


def as_image_tuple(got: object) -> ImageTuple | None:
    """An image source's answer as `(bytes, format, width, height)`: a tuple, or an object
    with `data`, `format`, `width`, `height` attributes (like `vge_analytics._images.ViewImage`)."""
    if got is None or isinstance(got, tuple):
        return got  # type: ignore[return-value]
    return (got.data, got.format, got.width, got.height)  # type: ignore[attr-defined]


def episode_lambda(ctx: RunContext, task: Task) -> float:
    """Lambda precedence: replay option > task > run.json > 5."""
    for value in (ctx.option_lambda, task.lam, ctx.run_lambda):
        if value is not None:
            return float(value)
    return DEFAULT_LAMBDA


def process_batch(
    state: WorkerState, ctx: RunContext, lines: list[tuple[int, bytes]]
) -> BatchResult:
    """Decode, check and replay each line of a batch, in order.

    The replayable episodes of the batch are replayed together by the columnar engine
    (`_columnar.py`); `VGE_REPLAY_ENGINE=scalar` (or `WorkerState.columnar = None`) uses
    `replay_episode` per episode instead: both give the same tables. MCAP files always
    come from `replay_episode`.

    The cyclic garbage collector is paused for the batch: the rows are acyclic (tuples,
    lists, strings), reference counting frees them, and the collector's scans of the
    growing batch otherwise cost a fifth of the replay time.
    """
    outcomes: list[LineOutcome | None] = []
    todo: list[tuple[int, int, EpisodeInput]] = []  # (outcome index, line number, episode)
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        for number, raw in lines:
            try:
                _prepare_line(state, ctx, number, raw, outcomes, todo)
            except Exception as exc:
                exc.vge_line = number  # type: ignore[attr-defined]
                raise
        episodes = [e for _, _, e in todo]
        scalar: dict[int, EpisodeResult] = {}
        if state.columnar is not None:
            try:
                tables = replay_columnar(
                    state.columnar,
                    episodes,
                    run_id=ctx.run_id,
                    model=ctx.model,
                    agent_kind=ctx.agent_kind,
                )
            except Exception as exc:
                state.columnar.reset()
                for _, number, e in todo:  # an episode at fault raises, naming its line
                    _replay_scalar(ctx, number, e)
                exc.vge_line = lines[0][0] if lines else None  # type: ignore[attr-defined]
                raise
        else:
            scalar = {j: _replay_scalar(ctx, number, e) for j, (_, number, e) in enumerate(todo)}
            tables = _scalar_tables([scalar[j] for j in range(len(todo))])
        for j, (at, number, e) in enumerate(todo):
            mcap_tmp = None
            if ctx.wants_mcap(e.task.episode_id):
                result = scalar.get(j) or _replay_scalar(ctx, number, e)
                mcap_tmp = _write_mcap(state, ctx, number, e.machine, result)
            outcomes[at] = LineOutcome(
                number,
                e.task.episode_id,
                True,
                None,
                None,
                tables.step_counts[j],
                tables.goal_counts[j],
                mcap_tmp,
            )
        return BatchResult(
            [o for o in outcomes if o is not None], tables.steps, tables.episodes, tables.goals
        )
    finally:
        if was_enabled:
            gc.enable()


def _replay_scalar(ctx: RunContext, number: int, e: EpisodeInput) -> EpisodeResult:
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
        )
    except Exception as exc:
        exc.vge_line = number  # type: ignore[attr-defined]
        raise


def _scalar_tables(results: list[EpisodeResult]) -> ColumnarBatch:
    return ColumnarBatch(
        rows_to_table([t for r in results for t in r.step_tuples], StepRow),
        rows_to_table([r.episode for r in results], EpisodeRow),
        rows_to_table([g for r in results for g in r.goals], GoalRow),
        [len(r.step_tuples) for r in results],
        [len(r.goals) for r in results],
    )


def _write_mcap(
    state: WorkerState, ctx: RunContext, number: int, machine: Machine, result: EpisodeResult
) -> str:
    mcap_tmp = f"{safe_file_name(result.episode.episode_id)}.L{number}.mcap.tmp"
    source = ctx.image_source

    def image(view: str, m: Machine = machine) -> ImageTuple | None:
        return None if source is None else state.image(source, m, view)

    with open(os.path.join(ctx.mcap_dir or "", mcap_tmp), "wb") as fh:
        write_episode_mcap(
            fh, machine, result, ssm_bytes=state.ssm(machine), image=image, library=ctx.library
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
        log = episode_decoder.decode(raw)
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
        reason = (
            f"device {device!r} (tasks.jsonl line {entry.line}) has no SSM file ssm/{device}.json"
        )
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
        reason = one_line(f"{exc} (tasks.jsonl line {entry.line})")
        outcomes.append(LineOutcome(number, eid, True, "task_error", reason))
        return
    todo.append(
        (len(outcomes), number, EpisodeInput(machine, task, setup, log, episode_lambda(ctx, task)))
    )
    outcomes.append(None)


# ------------------------------------------------------------------ worker processes

_worker_state: WorkerState | None = None


def init_worker(bench_dir: str) -> None:
    """Pool initializer: open the benchmark once per worker process."""
    global _worker_state
    _worker_state = WorkerState(Benchmark.open(bench_dir))


def run_batch(ctx: RunContext, lines: list[tuple[int, bytes]]) -> BatchResult | BatchFailure:
    """Pool task: like `process_batch`, but every error comes back as data."""
    assert _worker_state is not None, "init_worker was not called"
    return guarded_batch(_worker_state, ctx, lines)


def guarded_batch(
    state: WorkerState, ctx: RunContext, lines: list[tuple[int, bytes]]
) -> BatchResult | BatchFailure:
    try:
        return process_batch(state, ctx, lines)
    except Exception as exc:  # a bug or an I/O error: fatal, reported by the main process
        return BatchFailure(
            getattr(exc, "vge_line", None),
            one_line(f"replay failed: {type(exc).__name__}: {exc}"),
            traceback.format_exc(),
        )
