"""`replay_runs`: run logs -> Parquet tables, quarantine, manifest, MCAP (PROTOCOL §7).

The main process reads each episodes file line by line and cuts it into batches of
`BATCH_LINES` lines; batches are replayed in order (in-process, or by worker processes,
at most `AHEAD_PER_WORKER` per worker in flight) and their rows are written in batch order.
So memory does not grow with the log size and the output does not depend on the number of
workers.

Modules: `_reading` (run directories, lines in batches, ordered results), `_batch` (the
worker side), `_runjob` (one run: duplicates, quarantine, staging, swap-in), `_writer`
(atomic files, Parquet parts), `_outdir` (up-to-date check, files rebuilt from the manifest,
lock), `_manifest` (the manifest records, hashing, the runs table), `_mcap` (MCAP files).
"""

from __future__ import annotations

import math
import multiprocessing
import os
import shutil
from collections.abc import Iterable, Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import TYPE_CHECKING

import msgspec

from .._errors import ConfigError, InputError
from .._version import ENGINE_VERSION
from ._batch import (
    WorkerState,
    init_worker,
)
from ._load import Benchmark
from ._manifest import (
    Hasher,
    Manifest,
    RunEntry,
    RunOptions,
    read_manifest,
)
from ._mcap import ImageSource
from ._outdir import OutputLock, publish, run_inputs, up_to_date
from ._reading import LineReader, RunInput, ordered_results, read_runs
from ._runjob import STATE_DIR, RunJob

if TYPE_CHECKING:
    from rich.progress import Progress, TaskID

BATCH_LINES = 1024
"""Episode lines per batch (the unit of work of a worker; fixed, whatever the workers)."""
AHEAD_PER_WORKER = 2
"""Batches in flight per worker process."""


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
    """Episodes per second since the run started (display only; never written anywhere)."""
    t = progress.tasks[task]
    elapsed = t.elapsed
    return "-" if not elapsed or not t.completed else f"{t.completed / elapsed:,.0f}"


def _start_workers(workers: int, bench_dir: str) -> list[ProcessPoolExecutor]:
    """One single-process pool per worker: batch k of every run goes to worker k mod N, so
    runs that list the same episodes in the same order find each task's plan cached."""
    context = multiprocessing.get_context("spawn")
    return [
        ProcessPoolExecutor(
            max_workers=1, mp_context=context, initializer=init_worker, initargs=(bench_dir,)
        )
        for _ in range(workers)
    ]


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
    """Replay run directories against a benchmark into `out_dir` (PROTOCOL §7).

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
    runs = read_runs(run_dirs)
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise InputError(str(out), "output path exists and is not a directory")
    out.mkdir(parents=True, exist_ok=True)
    state_dir = out / STATE_DIR
    library = f"vge-analytics replay {ENGINE_VERSION}"
    replayed: list[str] = []
    skipped: list[str] = []

    with OutputLock(state_dir):
        for leftover in ("staging", "trash"):
            shutil.rmtree(state_dir / leftover, ignore_errors=True)
        previous = read_manifest(out)
        entries = {e.run_id: e for e in previous.runs} if previous else {}
        hasher = Hasher()
        local = WorkerState(bench)
        pools: list[ProcessPoolExecutor] = []
        bar = _make_progress(progress)
        try:
            if bar is not None:
                bar.start()
            for run in runs:
                run_id = run.header.run_id
                prev = entries.get(run_id)
                if prev is not None and not force:
                    current = up_to_date(prev, run, bench_given, options, hasher, out)
                    if current is not None:
                        entries[run_id] = msgspec.structs.replace(prev, inputs=current)
                        skipped.append(run_id)
                        if bar is not None:
                            bar.console.print(f"{run_id}: up to date, skipped (use --force)")
                        continue
                if workers > 1 and not pools:
                    pools = _start_workers(workers, bench_given)
                entries[run_id] = _replay_one(
                    run,
                    bench,
                    bench_given,
                    out,
                    options,
                    image_source,
                    library,
                    hasher,
                    pools,
                    local,
                    workers,
                    bar,
                )
                replayed.append(run_id)
                publish(out, entries)
            content = publish(out, entries)
        finally:
            if bar is not None:
                bar.stop()
            for pool in pools:
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
    pools: list[ProcessPoolExecutor],
    local: WorkerState,
    workers: int,
    bar: Progress | None,
) -> RunEntry:
    hasher(run.episodes)  # hash what is about to be read
    job = RunJob(run, bench, out, options, image_source, library)
    reader = LineReader(run.episodes, BATCH_LINES)
    task = None
    if bar is not None:
        task = bar.add_task(run.header.run_id, total=None, rate="-")
    try:
        results = ordered_results(
            reader.batches(), job.ctx, pools, local, AHEAD_PER_WORKER * workers
        )
        for batch_result in results:
            n = job.take(batch_result)
            if bar is not None and task is not None:
                bar.advance(task, n)
                bar.update(task, rate=_rate(bar, task))
        job.finish_reading(reader)
        inputs = run_inputs(run, bench_given, hasher, job.devices)
        entry = job.commit(inputs)
        if bar is not None and task is not None:
            bar.update(task, total=bar.tasks[task].completed)
        return entry
    except BaseException:
        job.abort()
        raise


__all__ = ["BATCH_LINES", "replay_runs"]
