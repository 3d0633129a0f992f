"""`replay_runs`: run logs -> Parquet tables, quarantine, manifest, MCAP (SPEC 7).

The main process reads each episodes file line by line and cuts it into batches of
`BATCH_LINES` lines; batches are replayed in order (in-process, or by worker processes,
at most `AHEAD_PER_WORKER` per worker in flight) and their rows are written in batch order.
So memory does not grow with the log size and the output does not depend on the number of
workers. Duplicates are decided here, where every line of a run is seen in order.

Outputs are staged under `OUT/.replay/staging/` and swapped in per run (see `_writer.py`);
`OUT/quarantine.jsonl`, `OUT/runs/runs.parquet` and `OUT/manifest.json` are rewritten
(atomically) after each run, from the per-run records of every run the manifest holds.
"""

from __future__ import annotations

import fcntl
import math
import multiprocessing
import os
import shutil
from collections import deque
from collections.abc import Iterable, Iterator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, BinaryIO

import msgspec
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from ._batch import (
    BatchFailure,
    BatchResult,
    RunContext,
    WorkerState,
    guarded_batch,
    init_worker,
    run_batch,
    safe_file_name,
)
from ._errors import ConfigError, InputError, WorkerError
from ._load import Benchmark, episodes_file, iter_lines, read_run_header
from ._manifest import (
    Divergence,
    FileRef,
    Hasher,
    Manifest,
    ManifestFile,
    RunCounts,
    RunEntry,
    RunInfo,
    RunInputs,
    RunOptions,
    RunOutputs,
    encode_manifest,
    read_manifest,
    runs_table,
    totals_of,
)
from ._mcap import ImageSource
from ._quarantine import QuarantineRecord, encode_record
from ._records import SCHEMA_VERSION, RunHeader
from ._tables import TABLE_ROWS, arrow_schema
from ._vocab import DEFAULT_LAMBDA
from ._writer import PartWriter, atomic_write, atomic_write_bytes, remove_dir, swap_in

if TYPE_CHECKING:
    from rich.progress import Progress, TaskID

BATCH_LINES = 64
"""Episode lines per batch (the unit of work of a worker; fixed, whatever the workers)."""
AHEAD_PER_WORKER = 2
"""Batches in flight per worker process."""
DIVERGENCE_FIELDS = ("feedback", "state", "view")
STATE_DIR = ".replay"


@dataclass(frozen=True)
class RunInput:
    run_dir: str  # as given
    header: RunHeader
    episodes: Path


def _check_run_id(run_id: str, path: Path) -> None:
    bad = (
        run_id.startswith(".")
        or any(c in run_id for c in "/\\=%")
        or any(c.isspace() or ord(c) < 32 for c in run_id)
    )
    if bad:
        raise InputError(
            str(path),
            f"run_id {run_id!r} cannot name a partition directory "
            "(no '/', '\\', '=', '%', whitespace, or leading '.')",
        )


def _read_runs(run_dirs: Sequence[str | os.PathLike[str]]) -> list[RunInput]:
    runs: dict[str, RunInput] = {}
    for given in run_dirs:
        run_dir = str(given)
        if not Path(run_dir).is_dir():
            raise InputError(run_dir, "run directory not found")
        header = read_run_header(run_dir)
        _check_run_id(header.run_id, Path(run_dir) / "run.json")
        other = runs.get(header.run_id)
        if other is not None:
            raise ConfigError(
                f"run_id {header.run_id!r} appears in two run directories: "
                f"{other.run_dir} and {run_dir}"
            )
        runs[header.run_id] = RunInput(run_dir, header, episodes_file(run_dir))
    return [runs[k] for k in sorted(runs)]


def _options(
    lam: float | None, mcap: bool, mcap_episodes: Iterable[str] | None, workers: int
) -> RunOptions:
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ConfigError(f"workers must be a positive integer, not {workers!r}")
    if lam is not None and not (isinstance(lam, (int, float)) and math.isfinite(lam) and lam > 0):
        raise ConfigError(f"lambda must be a positive number, not {lam!r}")
    episodes = None
    if mcap_episodes is not None:
        if isinstance(mcap_episodes, str):
            raise ConfigError("mcap_episodes must be a collection of episode ids, not a string")
        episodes = sorted(set(mcap_episodes))
        mcap = True
    return RunOptions(
        lam=None if lam is None else float(lam), mcap=bool(mcap), mcap_episodes=episodes
    )


# ----------------------------------------------------------------------------- reading


class LineReader:
    """Lines of an episodes file in batches; a read error ends the file (kept in `error`)."""

    def __init__(self, path: Path, batch_lines: int) -> None:
        self.path = path
        self.batch_lines = batch_lines
        self.last_line = 0
        self.error: InputError | None = None

    def batches(self) -> Iterator[list[tuple[int, bytes]]]:
        batch: list[tuple[int, bytes]] = []
        lines = iter_lines(self.path)
        while True:
            try:
                item = next(lines)
            except StopIteration:
                break
            except InputError as exc:
                self.error = exc
                break
            self.last_line = item[0]
            batch.append(item)
            if len(batch) >= self.batch_lines:
                yield batch
                batch = []
        if batch:
            yield batch


def _ordered_results(
    batches: Iterator[list[tuple[int, bytes]]],
    ctx: RunContext,
    pool: ProcessPoolExecutor | None,
    local: WorkerState,
    ahead: int,
) -> Iterator[BatchResult | BatchFailure]:
    """Results in batch order, with at most `ahead` batches in flight."""
    if pool is None:
        for batch in batches:
            yield guarded_batch(local, ctx, batch)
        return
    pending: deque[Future[BatchResult | BatchFailure]] = deque()
    try:
        for batch in batches:
            pending.append(pool.submit(run_batch, ctx, batch))
            if len(pending) >= ahead:
                yield pending.popleft().result()
        while pending:
            yield pending.popleft().result()
    except BrokenProcessPool:
        raise WorkerError(
            f"{ctx.file}: a replay worker process died (killed or out of memory; a script "
            "calling replay_runs with workers > 1 needs an `if __name__ == '__main__':` guard)"
        ) from None
    finally:
        for future in pending:
            future.cancel()


# ----------------------------------------------------------------------------- one run


@dataclass
class _Tally:
    lines_read: int = 0
    replayed: int = 0
    steps: int = 0
    truncated: int = 0
    diverged: int = 0
    compared: int = 0
    episodes_diverged: int = 0
    goals: int = 0
    mcap_files: int = 0
    by_field: dict[str, int] = field(default_factory=lambda: dict.fromkeys(DIVERGENCE_FIELDS, 0))
    by_kind: dict[str, int] = field(default_factory=dict)

    def add_tables(self, steps: pa.Table, episodes: pa.Table, goals: pa.Table) -> None:
        self.steps += steps.num_rows
        self.goals += goals.num_rows
        if steps.num_rows:
            self.truncated += pc.sum(steps["truncated"]).as_py() or 0
            diverged = steps["diverged"]
            self.compared += len(diverged) - diverged.null_count
            self.diverged += pc.sum(diverged).as_py() or 0
            flat = pc.list_flatten(steps["diverged_fields"])
            if len(flat):
                for item in pc.value_counts(flat).to_pylist():
                    name = item["values"]
                    self.by_field[name] = self.by_field.get(name, 0) + item["counts"]
        if episodes.num_rows:
            self.episodes_diverged += pc.sum(pc.greater(episodes["diverged_steps"], 0)).as_py() or 0


def _keep_mask(n: int, drops: list[tuple[int, int]]) -> pa.Array:
    keep = [True] * n
    for start, count in drops:
        keep[start : start + count] = [False] * count
    return pa.array(keep, pa.bool_())


class _RunReplay:
    """Replays one run into a staging directory, then swaps it into OUT."""

    def __init__(
        self,
        run: RunInput,
        bench: Benchmark,
        out: Path,
        options: RunOptions,
        image_source: ImageSource | None,
        library: str,
    ) -> None:
        self.run = run
        self.bench = bench
        self.out = out
        self.options = options
        self.state_dir = out / STATE_DIR
        self.staging = self.state_dir / "staging" / run.header.run_id
        if self.staging.exists():
            shutil.rmtree(self.staging)
        self.staging.mkdir(parents=True)
        self.mcap_dir = self.staging / "mcap" if options.mcap else None
        if self.mcap_dir is not None:
            self.mcap_dir.mkdir()
        h = run.header
        self.ctx = RunContext(
            run_id=h.run_id,
            model=h.model,
            agent_kind=h.agent_kind,
            run_lambda=h.lam,
            option_lambda=options.lam,
            file=str(run.episodes),
            mcap_dir=None if self.mcap_dir is None else str(self.mcap_dir),
            mcap_episodes=(
                None if options.mcap_episodes is None else frozenset(options.mcap_episodes)
            ),
            image_source=image_source,
            library=library,
        )
        self.writers = {
            name: PartWriter(self.staging / name, arrow_schema(row_type))
            for name, row_type in TABLE_ROWS.items()
        }
        self.seen: dict[str, int] = {}
        self.devices: dict[str, None] = {}
        self.tally = _Tally()
        self._quarantine_path = self.staging / "quarantine.jsonl"
        self._quarantine: BinaryIO = open(self._quarantine_path, "wb")  # noqa: SIM115

    def quarantine(self, line: int, episode_id: str | None, kind: str, reason: str) -> None:
        record = QuarantineRecord(
            run_id=self.ctx.run_id,
            file=self.ctx.file,
            line=line,
            episode_id=episode_id,
            kind=kind,
            reason=reason,
        )
        self._quarantine.write(encode_record(record))
        self.tally.by_kind[kind] = self.tally.by_kind.get(kind, 0) + 1

    def take(self, result: BatchResult | BatchFailure) -> int:
        """Account for one batch result and write its rows; returns the lines it held."""
        if isinstance(result, BatchFailure):
            raise InputError(self.ctx.file, result.message, result.line) from RuntimeError(
                result.details
            )
        tally = self.tally
        drops: list[tuple[int, int]] = []
        step_drops: list[tuple[int, int]] = []
        goal_drops: list[tuple[int, int]] = []
        episode_pos = step_pos = goal_pos = 0
        for o in result.outcomes:
            tally.lines_read += 1
            kind, reason = o.kind, o.reason
            if o.decoded and o.episode_id is not None:
                first = self.seen.get(o.episode_id)
                if first is not None:
                    kind = "duplicate_episode"
                    reason = (
                        f"episode {o.episode_id!r} already appeared on line {first}; "
                        "only the first occurrence is replayed"
                    )
                else:
                    self.seen[o.episode_id] = o.line
                    entry = self.bench.tasks.get(o.episode_id)
                    if entry is not None:
                        self.devices.setdefault(entry.task.device_id)
            if o.kind is None:  # replayed by the worker
                if kind is None:
                    tally.replayed += 1
                    if o.mcap_tmp is not None:
                        self._publish_mcap(o.mcap_tmp, o.episode_id)
                else:  # a duplicate: drop its rows
                    drops.append((episode_pos, 1))
                    step_drops.append((step_pos, o.n_steps))
                    goal_drops.append((goal_pos, o.n_goals))
                    if o.mcap_tmp is not None and self.mcap_dir is not None:
                        (self.mcap_dir / o.mcap_tmp).unlink(missing_ok=True)
                episode_pos += 1
                step_pos += o.n_steps
                goal_pos += o.n_goals
            if kind is not None:
                self.quarantine(o.line, o.episode_id, kind, reason or "")
        steps, episodes, goals = result.steps, result.episodes, result.goals
        if drops:
            steps = steps.filter(_keep_mask(steps.num_rows, step_drops))
            episodes = episodes.filter(_keep_mask(episodes.num_rows, drops))
            goals = goals.filter(_keep_mask(goals.num_rows, goal_drops))
        tally.add_tables(steps, episodes, goals)
        self.writers["steps"].write(steps)
        self.writers["episodes"].write(episodes)
        self.writers["goals"].write(goals)
        return len(result.outcomes)

    def _publish_mcap(self, tmp_name: str, episode_id: str | None) -> None:
        assert self.mcap_dir is not None and episode_id is not None
        os.replace(self.mcap_dir / tmp_name, self.mcap_dir / f"{safe_file_name(episode_id)}.mcap")
        self.tally.mcap_files += 1

    def finish_reading(self, reader: LineReader) -> None:
        if reader.error is not None:
            self.tally.lines_read += 1
            self.quarantine(
                reader.last_line + 1,
                None,
                "truncated_file",
                f"the file cannot be read from line {reader.last_line + 1} on: "
                f"{reader.error.message}",
            )

    def abort(self) -> None:
        for writer in self.writers.values():
            writer.abort()
        self._quarantine.close()
        shutil.rmtree(self.staging, ignore_errors=True)

    def commit(self, inputs: RunInputs) -> RunEntry:
        """Close the staged files and swap the run's partitions into OUT."""
        files = {name: w.close() for name, w in self.writers.items()}
        self._quarantine.close()
        run_id = self.ctx.run_id
        trash = self.state_dir / "trash"
        for name in TABLE_ROWS:
            swap_in(self.staging / name, self.out / name / f"run_id={run_id}", trash)
        if self.mcap_dir is not None:
            swap_in(self.mcap_dir, self.out / "mcap" / run_id, trash)
        else:
            remove_dir(self.out / "mcap" / run_id, trash)
        qdir = self.state_dir / "quarantine"
        qdir.mkdir(parents=True, exist_ok=True)
        os.replace(self._quarantine_path, qdir / f"{run_id}.jsonl")
        shutil.rmtree(self.staging, ignore_errors=True)
        t = self.tally
        h = self.run.header
        return RunEntry(
            run_id=run_id,
            engine_version=_engine_version(),
            inputs=inputs,
            options=self.options,
            run=RunInfo(model=h.model, agent_kind=h.agent_kind, lam=h.lam, meta=h.meta),
            counts=RunCounts(
                lines_read=t.lines_read,
                replayed=t.replayed,
                quarantined=sum(t.by_kind.values()),
                steps=t.steps,
                truncated_steps=t.truncated,
                diverged_steps=t.diverged,
                goals=t.goals,
                mcap_files=t.mcap_files,
            ),
            quarantine=dict(sorted(t.by_kind.items())),
            divergence=Divergence(
                steps_compared=t.compared,
                steps_diverged=t.diverged,
                episodes_diverged=t.episodes_diverged,
                by_field=dict(sorted(t.by_field.items())),
            ),
            outputs=RunOutputs(
                steps=[f"steps/run_id={run_id}/{f}" for f in files["steps"]],
                episodes=[f"episodes/run_id={run_id}/{f}" for f in files["episodes"]],
                goals=[f"goals/run_id={run_id}/{f}" for f in files["goals"]],
                mcap=None if self.mcap_dir is None else f"mcap/{run_id}",
            ),
        )


def _engine_version() -> str:
    from . import ENGINE_VERSION

    return ENGINE_VERSION


# ------------------------------------------------------------------------ inputs, skip


def _inputs(run: RunInput, bench_dir: str, hasher: Hasher, devices: Iterable[str]) -> RunInputs:
    ssm_dir = Path(bench_dir) / "ssm"
    return RunInputs(
        run_dir=run.run_dir,
        run_json=hasher.ref(Path(run.run_dir) / "run.json"),
        episodes=hasher.ref(run.episodes),
        bench=bench_dir,
        tasks=hasher.ref(Path(bench_dir) / "tasks.jsonl"),
        ssm={d: hasher.ref(ssm_dir / f"{d}.json") for d in sorted(devices)},
    )


def _up_to_date(
    prev: RunEntry, run: RunInput, bench_dir: str, options: RunOptions, hasher: Hasher, out: Path
) -> RunInputs | None:
    """The run's current inputs if `prev` replayed exactly them (and its outputs exist)."""
    if prev.engine_version != _engine_version() or prev.options != options:
        return None
    now = _inputs(run, bench_dir, hasher, prev.inputs.ssm)
    same = (
        now.run_json.sha256 == prev.inputs.run_json.sha256
        and now.episodes.sha256 == prev.inputs.episodes.sha256
        and now.tasks.sha256 == prev.inputs.tasks.sha256
        and all(now.ssm[d].sha256 == ref.sha256 for d, ref in prev.inputs.ssm.items())
    )
    if not same:
        return None
    outputs = prev.outputs
    expected = [*outputs.steps, *outputs.episodes, *outputs.goals]
    if outputs.mcap is not None:
        expected.append(outputs.mcap)
    expected.append(f"{STATE_DIR}/quarantine/{prev.run_id}.jsonl")
    if not all((out / p).exists() for p in expected):
        return None
    return now


# ------------------------------------------------------------------------- publishing


def _publish(out: Path, entries: dict[str, RunEntry]) -> ManifestFile:
    """Rewrite quarantine.jsonl, runs/runs.parquet and manifest.json from the run entries."""
    runs = [entries[k] for k in sorted(entries)]
    qdir = out / STATE_DIR / "quarantine"

    def write_quarantine(fh: BinaryIO) -> None:
        for r in runs:
            path = qdir / f"{r.run_id}.jsonl"
            if path.exists():
                with open(path, "rb") as src:
                    shutil.copyfileobj(src, fh)

    atomic_write(out / "quarantine.jsonl", write_quarantine)
    (out / "runs").mkdir(exist_ok=True)
    table = runs_table(runs, DEFAULT_LAMBDA)
    atomic_write(out / "runs" / "runs.parquet", lambda fh: pq.write_table(table, fh))
    manifest = ManifestFile(
        engine_version=_engine_version(),
        schema_version=SCHEMA_VERSION,
        totals=totals_of(runs),
        runs=runs,
    )
    atomic_write_bytes(out / "manifest.json", encode_manifest(manifest))
    return manifest


class _Lock:
    """One `vge replay` at a time per output directory (released if the process dies)."""

    def __init__(self, state_dir: Path) -> None:
        state_dir.mkdir(parents=True, exist_ok=True)
        self.path = state_dir / "lock"

    def __enter__(self) -> _Lock:
        self._fh = open(self.path, "wb")  # noqa: SIM115
        try:
            fcntl.flock(self._fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            self._fh.close()
            raise ConfigError(
                f"{self.path.parent.parent}: another vge replay is writing to this directory"
            ) from None
        return self

    def __exit__(self, *exc: object) -> None:
        fcntl.flock(self._fh, fcntl.LOCK_UN)
        self._fh.close()


# ---------------------------------------------------------------------------- progress


def _make_progress(enabled: bool) -> Progress | None:
    if not enabled:
        return None
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        Progress,
        SpinnerColumn,
        TextColumn,
        TimeElapsedColumn,
    )

    console = Console(stderr=True)
    if not console.is_terminal:
        return None
    return Progress(
        SpinnerColumn(),
        TextColumn("[bold]{task.description}"),
        BarColumn(bar_width=None),
        TextColumn("{task.completed:>9,.0f} episodes"),
        TextColumn("{task.fields[rate]:>8} ep/s"),
        TimeElapsedColumn(),
        console=console,
        transient=False,
    )


def _rate(progress: Progress, task: TaskID) -> str:
    speed = progress.tasks[task].speed  # rich's own moving average (display only)
    return "-" if speed is None else f"{speed:,.0f}"


# ------------------------------------------------------------------------------ public


def replay_runs(
    run_dirs: Sequence[str | os.PathLike[str]],
    bench_dir: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    *,
    lam: float | None = None,
    workers: int = 1,
    mcap: bool = False,
    mcap_episodes: Iterable[str] | None = None,
    force: bool = False,
    progress: bool = True,
    image_source: ImageSource | None = None,
) -> Manifest:
    """Replay run directories against a benchmark into `out_dir` (SPEC 7).

    Writes `steps/`, `episodes/`, `goals/` (hive-partitioned by `run_id`), `runs/runs.parquet`,
    `quarantine.jsonl`, `manifest.json` and, with `mcap`, `mcap/<run_id>/<episode_id>.mcap`.
    A run whose inputs (sha256), options and engine version match the manifest is skipped
    unless `force`. Lambda precedence: `lam` > task `lambda` > run.json `lambda` > 5.
    `mcap_episodes` limits MCAP files to those episode ids (and implies `mcap`).
    `image_source(machine, view)` gives view images for MCAP (picklable when `workers > 1`).
    Raises `VGEError` subclasses on fatal problems; bad records are quarantined instead.
    """
    options = _options(lam, mcap, mcap_episodes, workers)
    if not run_dirs:
        raise ConfigError("no run directories given")
    bench_given = str(bench_dir)
    bench = Benchmark.open(bench_given)
    runs = _read_runs(run_dirs)
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise InputError(str(out), "output path exists and is not a directory")
    out.mkdir(parents=True, exist_ok=True)
    state_dir = out / STATE_DIR
    library = f"vge-analytics replay {_engine_version()}"
    replayed: list[str] = []
    skipped: list[str] = []

    with _Lock(state_dir):
        for leftover in ("staging", "trash"):
            shutil.rmtree(state_dir / leftover, ignore_errors=True)
        previous = read_manifest(out)
        entries = {e.run_id: e for e in previous.runs} if previous else {}
        hasher = Hasher()
        local = WorkerState(bench)
        pool: ProcessPoolExecutor | None = None
        bar = _make_progress(progress)
        try:
            if bar is not None:
                bar.start()
            for run in runs:
                run_id = run.header.run_id
                prev = entries.get(run_id)
                if prev is not None and not force:
                    current = _up_to_date(prev, run, bench_given, options, hasher, out)
                    if current is not None:
                        entries[run_id] = msgspec.structs.replace(prev, inputs=current)
                        skipped.append(run_id)
                        if bar is not None:
                            bar.console.print(f"{run_id}: up to date, skipped (use --force)")
                        continue
                if workers > 1 and pool is None:
                    pool = ProcessPoolExecutor(
                        max_workers=workers,
                        mp_context=multiprocessing.get_context("spawn"),
                        initializer=init_worker,
                        initargs=(bench_given,),
                    )
                entries[run_id] = _replay_one(
                    run,
                    bench,
                    bench_given,
                    out,
                    options,
                    image_source,
                    library,
                    hasher,
                    pool,
                    local,
                    workers,
                    bar,
                )
                replayed.append(run_id)
                _publish(out, entries)
            content = _publish(out, entries)
        finally:
            if bar is not None:
                bar.stop()
            if pool is not None:
                pool.shutdown(wait=True, cancel_futures=True)
            shutil.rmtree(state_dir / "staging", ignore_errors=True)
    return Manifest(
        path=out / "manifest.json",
        content=content,
        requested=[r.header.run_id for r in runs],
        replayed=replayed,
        skipped=skipped,
    )


def _replay_one(
    run: RunInput,
    bench: Benchmark,
    bench_given: str,
    out: Path,
    options: RunOptions,
    image_source: ImageSource | None,
    library: str,
    hasher: Hasher,
    pool: ProcessPoolExecutor | None,
    local: WorkerState,
    workers: int,
    bar: Progress | None,
) -> RunEntry:
    hasher(run.episodes)  # hash what is about to be read
    job = _RunReplay(run, bench, out, options, image_source, library)
    reader = LineReader(run.episodes, BATCH_LINES)
    task = None
    if bar is not None:
        task = bar.add_task(run.header.run_id, total=None, rate="-")
    try:
        results = _ordered_results(
            reader.batches(), job.ctx, pool, local, AHEAD_PER_WORKER * workers
        )
        for batch_result in results:
            n = job.take(batch_result)
            if bar is not None and task is not None:
                bar.advance(task, n)
                bar.update(task, rate=_rate(bar, task))
        job.finish_reading(reader)
        inputs = _inputs(run, bench_given, hasher, job.devices)
        entry = job.commit(inputs)
        if bar is not None and task is not None:
            bar.update(task, total=bar.tasks[task].completed)
        return entry
    except BaseException:
        job.abort()
        raise


__all__ = ["BATCH_LINES", "FileRef", "Manifest", "replay_runs"]
