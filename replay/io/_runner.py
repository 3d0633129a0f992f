"""`replay_runs`: run logs -> Parquet tables, quarantine, manifest, MCAP (PROTOCOL §7).

The words of the way through, each in its module:
- the runner (here): the runs to replay (the up-to-date ones skipped), one job per run, the
  progress bar, the manifest published after each run;
- the job (`_job.RunJob`): one run in the main process; it reads its episodes file and cuts
  it into batches, takes their reports in line order (duplicates, quarantine, counts) and
  commits the run when its last batch is in;
- the batch (`_batch`): a task of lines with the context of its run, replayed and written
  as one Parquet part per table (and the MCAP files) by `replay_batch`, here or in worker
  processes (`_executor`, `_worker`) or Ray tasks (`_ray`), at most `AHEAD_PER_WORKER`
  batches per worker in flight, the next run's batches following the current one's without
  a pause.
Memory does not grow with the log size and the files do not depend on the number of workers.
"""

from __future__ import annotations

import functools
import math
import os
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from typing import TYPE_CHECKING

import msgspec

from .._errors import ConfigError, InputError
from . import _files
from ._batch import BatchTask, replay_batch
from ._executor import Executor, InProcess, in_order, make_executor
from ._files import STATE_DIR
from ._fs import Location, location
from ._images import ImageSource
from ._job import RunJob
from ._layout import manifest_path
from ._lines import MAX_RECORD_BYTES
from ._load import Benchmark
from ._manifest import Hasher, Manifest, RunEntry, RunInputs, RunOptions, read_manifest
from ._outdir import OutputLock, prepare_publish, publish, run_inputs, up_to_date
from ._reading import RunInput, read_runs
from ._worker import WorkerState, adopt

if TYPE_CHECKING:
    from rich.progress import Progress, TaskID

AHEAD_PER_WORKER = 2
"""Batches in flight per worker process."""


def _options(
    lam: float | None,
    mcap: bool,
    mcap_episodes: Iterable[str] | None,
    workers: int,
    max_record_bytes: int,
) -> RunOptions:
    for name, value in (("workers", workers), ("max_record_bytes", max_record_bytes)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise ConfigError(f"{name} must be a positive integer, not {value!r}")
    if lam is not None and not (isinstance(lam, (int, float)) and math.isfinite(lam) and lam > 0):
        raise ConfigError(f"lambda must be a positive number, not {lam!r}")
    episodes = None
    if mcap_episodes is not None:
        if isinstance(mcap_episodes, str):
            raise ConfigError("mcap_episodes must be a collection of episode ids, not a string")
        episodes = sorted(set(mcap_episodes))
        mcap = True
    return RunOptions(
        lam=None if lam is None else float(lam),
        mcap=bool(mcap),
        mcap_episodes=episodes,
        max_record_bytes=max_record_bytes,
    )


def _make_progress(enabled: bool, *, cluster: bool = False) -> Progress | None:
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
    columns = [
        SpinnerColumn(),
        TextColumn("[bold]{task.description}"),
        BarColumn(bar_width=None),
        TextColumn("{task.completed:>9,.0f} episodes"),
        TextColumn("{task.fields[rate]:>8} ep/s"),
    ]
    if cluster:
        columns.append(TextColumn("{task.fields[nodes]} node(s)"))
    return Progress(*columns, TimeElapsedColumn(), console=console, transient=False)


def _rate(progress: Progress, task: TaskID) -> str:
    """Episodes per second since the run started (display only; never written anywhere)."""
    t = progress.tasks[task]
    elapsed = t.elapsed
    return "-" if not elapsed or not t.completed else f"{t.completed / elapsed:,.0f}"


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
    ray: str | None = None,
    max_record_bytes: int = MAX_RECORD_BYTES,
) -> Manifest:
    """Replay run directories against a benchmark into `out_dir` (PROTOCOL §7).

    Writes `steps/`, `episodes/`, `goals/` (hive-partitioned by `run_id`), `runs/runs.parquet`,
    `quarantine.jsonl`, `manifest.json` and, with `mcap`, `mcap/<run_id>/<episode_id>.mcap`.
    A run whose inputs (sha256), options and engine version match the manifest is skipped
    unless `force`. Lambda precedence: `lam` > task `lambda` > run.json `lambda` > 5.
    `mcap_episodes` limits MCAP files to those episode ids (and implies `mcap`).
    `image_source(machine, view)` gives view images for MCAP (picklable when `workers > 1`).
    `ray` replays the batches as Ray tasks instead of local workers (`auto`: the cluster this
    host belongs to or `RAY_ADDRESS`; `local`: one started in this process; or an address);
    every node must reach `bench_dir`, `out_dir` and the image source (docs/SCALE.md).
    `max_record_bytes` bounds an episode line: a longer one is quarantined as
    `record_too_large` and ends the reading of its file (PROTOCOL §1.5).
    Run directories, `bench_dir` and `out_dir` are local paths or URIs of pyarrow's
    filesystems (`s3://bucket/out`, `gs://...`, `file:///...`); in an object store the
    manifest is the commit marker and the writer lock is a lease object (docs/SCALE.md).
    Raises `VGEError` subclasses on fatal problems; bad records are quarantined instead.
    """
    options = _options(lam, mcap, mcap_episodes, workers, max_record_bytes)
    if not run_dirs:
        raise ConfigError("no run directories given")
    bench_given = str(bench_dir)
    bench = Benchmark.open(bench_given)
    runs = read_runs(run_dirs)
    out = _output_dir(out_dir)
    state_dir = out / STATE_DIR
    replayed: list[str] = []

    with OutputLock(out) as lock:
        entries = _previous_entries(out)
        hasher = Hasher()
        todo, skipped = _runs_to_replay(runs, entries, force, bench_given, options, hasher, out)
        adopt(WorkerState(bench), bench_given)  # the main process replays with this one

        bar = _make_progress(progress, cluster=ray is not None)
        try:
            with _running(todo, workers, ray, bench_given) as executor:
                if bar is not None:
                    bar.start()
                    for run_id in skipped:
                        bar.console.print(f"{run_id}: up to date, skipped (use --force)")
                for job in _replay_all(
                    todo, bench, bench_given, out, options, image_source, hasher, executor, bar,
                    functools.partial(_commit, out, entries, lock),
                ):  # fmt: skip
                    replayed.append(job.ctx.run_id)
                lock.check()
                content = publish(out, entries)
        finally:
            if bar is not None:
                bar.stop()
            (state_dir / "staging").rmtree()
    manifest_file = manifest_path(out)
    return Manifest(
        path=manifest_file.local if manifest_file.local is not None else str(manifest_file),
        content=content,
        requested=[r.header.run_id for r in runs],
        replayed=replayed,
        skipped=skipped,
        nodes=dict(sorted(executor.nodes.items())),
    )


@contextmanager
def _running(todo: list[RunInput], workers: int, ray: str | None, bench: str) -> Iterator[Executor]:
    """The executor of the batches (this process alone when nothing is to be replayed),
    closed when they are done. Made once this process has opened `bench` and before it
    starts a thread (the reader, the progress bar), so that its workers are forked with the
    engine imported and `bench` open (`WorkerProcesses`); they use nothing else of this
    process."""
    executor = make_executor(workers, ray, bench, fork=True) if todo else InProcess()
    try:
        yield executor
    finally:
        executor.close()


def _output_dir(given: str | os.PathLike[str]) -> Location:
    out = location(given)
    if out.is_file():
        raise InputError(str(out), "output path exists and is not a directory")
    out.mkdir()
    return out


def _previous_entries(out: Location) -> dict[str, RunEntry]:
    """The runs the manifest holds, by id, once what an interrupted replay left behind is
    gone (held under the writer lock)."""
    for leftover in ("staging", "trash"):
        (out / STATE_DIR / leftover).rmtree()
    previous = read_manifest(out)
    return {e.run_id: e for e in previous.runs} if previous else {}


def _commit(
    out: Location, entries: dict[str, RunEntry], lock: OutputLock, job: RunJob, inputs: RunInputs
) -> None:
    """Put a replayed run into OUT so that its partitions, the runs table and the manifest
    change together or not at all: everything is written first (the run in staging, OUT's
    three files beside their places), then moved in by renames, the manifest last. A full
    disk or a late error while writing leaves OUT as it was.

    Without renames (an object store) a run's files are replaced one by one: the run is
    taken out of the manifest (the commit marker) first, so no reader trusts a half-replaced
    run and an interruption leaves it to be replayed."""
    run_id = job.ctx.run_id
    lock.check()  # an object store's lease: still ours, before anything changes
    if out.local is None and entries.pop(run_id, None) is not None:
        publish(out, entries)
    entry, quarantine = job.stage(inputs)
    publishing = prepare_publish(out, {**entries, run_id: entry}, {run_id: quarantine})
    job.swap_in()
    publishing.commit()
    entries[run_id] = entry


def _runs_to_replay(
    runs: list[RunInput],
    entries: dict[str, RunEntry],
    force: bool,
    bench_given: str,
    options: RunOptions,
    hasher: Hasher,
    out: Location,
) -> tuple[list[RunInput], list[str]]:
    """The runs to replay, and the ids of those skipped as up to date (unless `force`),
    whose `entries` get their inputs as given this time."""
    todo: list[RunInput] = []
    skipped: list[str] = []
    for run in runs:
        prev = entries.get(run.header.run_id)
        if prev is not None and not force:
            current = up_to_date(prev, run, bench_given, options, hasher, out)
            if current is not None:
                entries[run.header.run_id] = msgspec.structs.replace(prev, inputs=current)
                skipped.append(run.header.run_id)
                continue
        todo.append(run)
    return todo, skipped


def _replay_all(
    runs: list[RunInput],
    bench: Benchmark,
    bench_given: str,
    out: Location,
    options: RunOptions,
    image_source: ImageSource | None,
    hasher: Hasher,
    executor: Executor,
    bar: Progress | None,
    commit: Callable[[RunJob, RunInputs], None],
) -> Iterator[RunJob]:
    """Replay the runs, yielding each run's job once `commit(job, inputs)` put it into OUT
    (in order)."""
    open_jobs: list[RunJob] = []
    bars: dict[str, TaskID] = {}

    def items() -> Iterator[tuple[RunJob, BatchTask | None]]:
        for run in runs:
            hasher(run.episodes)  # hash what is about to be read
            job = RunJob(
                run, bench, bench_given, out, options, image_source, _files.ROW_GROUP_ROWS
            )
            open_jobs.append(job)
            if bar is not None:
                bars[job.ctx.run_id] = bar.add_task(job.ctx.run_id, total=None, rate="-", nodes=0)
            for task in job.batches():
                yield job, task
            yield job, None  # the end of the run, in order after its batches

    try:
        ahead = AHEAD_PER_WORKER * executor.slots
        for job, task, result in in_order(executor, replay_batch, items(), ahead):
            if task is not None and result is not None:
                n = job.take(task, result, redo=replay_batch)
                if bar is not None:
                    task_id = bars[job.ctx.run_id]
                    bar.advance(task_id, n)
                    bar.update(task_id, rate=_rate(bar, task_id), nodes=len(executor.nodes))
                continue
            job.finish_reading()
            inputs = run_inputs(job.run, bench_given, hasher, job.devices)
            commit(job, inputs)
            open_jobs.remove(job)
            if bar is not None:
                task_id = bars[job.ctx.run_id]
                bar.update(task_id, total=bar.tasks[task_id].completed)
            yield job
    except BaseException:
        for job in open_jobs:
            job.abort()
        raise
