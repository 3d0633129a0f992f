"""`vge run`: an agent plays episodes of a benchmark through `vge/Device-v0`, and the run
directory gets what `vge replay` reads.

Before the first episode the agent is checked (`LiveAgent.check`: a model server that
cannot be reached, refuses the key or does not know the model fails there, and nothing is
written). Each episode is played by one worker thread with an environment of its own
(`_worker.py`); the main thread alone writes the run directory (`_rundir.py`).

What stops a run before the end of its selection (PROTOCOL §10.3), the episodes written so
far staying for `--resume`:
- an error the agent cannot go on from (`AgentError`; a request the server refuses for
  good is one), raised as it is;
- `max_consecutive_failures` infrastructure failures in a row, across episodes
  (`RunStoppedError`): a server that went away is not asked again for every episode left.

Nothing in the files depends on the clock unless the agent measures time (tokens, latency
and timestamps of `openai:` agents).
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ThreadPoolExecutor, wait
from dataclasses import dataclass, field
from pathlib import Path

import msgspec

import replay
from replay.io import run_json_path

from .._errors import RequestRefusedError, RunDirError, RunStoppedError
from .._nearest import nearest_hint
from ._agents import LiveAgent
from ._continue import Source, SourceRun
from ._header import Counters, RunOptions, check_resume, run_header
from ._rundir import FailureRecord, RunDir
from ._worker import Failed, Finished, Outcome, Worker, replayed_success


@dataclass(frozen=True, slots=True)
class RunSummary:
    out: Path
    header: replay.RunHeader
    counters: Counters
    failures: list[FailureRecord]
    skipped: list[str] = field(default_factory=list)
    """Tasks that cannot be played, each with its reason (a continuation's first: the lines
    of its source that are not episodes, each naming its file and line)."""
    extended_from: int | None = None
    """The episodes the run had selected before `--resume` extended it (None: not extended)."""

    @property
    def complete(self) -> bool:
        return not self.failures


def select_episodes(
    bench: replay.Benchmark, episodes: Sequence[str] | None, limit: int | None
) -> list[str]:
    """The episodes to play, in order: those named (in the order given) or every task of
    `tasks.jsonl` (in file order), then the first `limit`."""
    return _chosen(bench.tasks, str(bench.tasks_path), episodes, limit)


def _chosen(
    available: Mapping[str, object], where: str, episodes: Sequence[str] | None, limit: int | None
) -> list[str]:
    """`available`'s ids in order, or those `episodes` names (each must be one of them),
    then the first `limit`."""
    if episodes is None:
        chosen = list(available)
    else:
        chosen = list(dict.fromkeys(episodes))
        unknown = [e for e in chosen if e not in available]
        if unknown:
            raise RunDirError(
                f"--episodes: not in {where}: {', '.join(map(repr, unknown[:5]))}"
                + (f" and {len(unknown) - 5} more" if len(unknown) > 5 else "")
                + nearest_hint(unknown[0], list(available), "episode")
            )
    if limit is not None:
        chosen = chosen[:limit]
    return chosen


class _Run:
    """The bookkeeping of one `run_live`: what is finished, failed and skipped, and the
    rule of consecutive failures."""

    def __init__(self, rundir: RunDir, counters: Counters, limit: int) -> None:
        self.rundir = rundir
        self.counters = counters
        self.limit = limit
        self.finished: dict[str, bytes] = {}
        self.failures: dict[str, FailureRecord] = {}
        self.skipped: list[str] = []
        self.in_a_row = 0
        """Infrastructure failures since the last finished episode."""

    def take(self, result: Outcome) -> None:
        """Write what an episode came to."""
        if isinstance(result, Finished):
            self.rundir.append(result.line)
            self.finished[result.episode_id] = result.line
            self.counters.add(result.log, result.success)
            self.in_a_row = 0
        elif isinstance(result, Failed):
            self.rundir.append_failure(result.record)
            self.failures[result.record.episode_id] = result.record
            self.counters.failures += 1
            self.in_a_row += 1
        else:
            self.skipped.append(f"{result.episode_id}: {result.reason}")
            self.counters.skipped += 1

    def too_many_failures(self, last: FailureRecord) -> RunStoppedError | None:
        if not self.limit or self.in_a_row < self.limit:
            return None
        return RunStoppedError(
            f"stopped after {self.in_a_row} infrastructure failures in a row (last: "
            f"{last.reason}); {self.written()}"
        )

    def written(self) -> str:
        c = self.counters
        return (
            f"{c.finished} of {c.selected} episodes written to {self.rundir.root}: "
            "the same command with --resume continues"
        )


def run_live(
    agent: LiveAgent,
    options: RunOptions,
    progress: Callable[[Counters], None] | None = None,
) -> RunSummary:
    """Play the selected episodes (those not finished yet, with `resume`) and complete the
    run directory. Raises `AgentError` when the agent cannot go on, `RunStoppedError` after
    too many infrastructure failures in a row (the episodes finished so far stay written:
    `--resume` continues)."""
    _check_options(options)
    options = msgspec.structs.replace(options, bench=Path(options.bench), out=Path(options.out))
    bench = replay.Benchmark.open(options.bench)
    source: Source | None = None
    if options.continuation is None:
        selection = select_episodes(bench, options.episodes, options.limit)
    else:
        options, source = _continuing(options)
        selection = _chosen(source.run.lines, str(source.run.root), options.episodes, options.limit)
    counters = Counters(
        selected=len(selection),
        prices=replay.semantics.Prices(options.prompt_price, options.completion_price),
    )
    unread: tuple[str, ...] = ()
    if source is not None and options.episodes is None:
        # Lines of the source that are not episodes: the continuation is not complete.
        unread, counters.source_unread = source.run.unread, source.run.unread_count
    rundir = RunDir(options.out)
    header = run_header(agent, options, counters)
    before: replay.RunHeader | None = None
    if options.resume:
        before = rundir.read_header()
        check_resume(before, header)
    else:
        rundir.check_new()  # before the server is asked
    agent.check()  # before anything is written
    run = _Run(rundir, counters, options.max_consecutive_failures)
    if before is not None:
        # Episodes that failed before are not finished: they are played again.
        run.finished = rundir.finished()
        chosen = set(selection)
        outside = [e for e in run.finished if e not in chosen]
        if outside:
            raise RunDirError(
                f"{rundir.episodes_path} holds episode {outside[0]!r}, which is not selected "
                "(--resume may add episodes to a run, not take them away)"
            )
        decoder = msgspec.json.Decoder(replay.EpisodeLog)
        for line in run.finished.values():
            log = decoder.decode(line)
            counters.add(log, replayed_success(bench, log, header.lam))
    else:
        rundir.create()
    rundir.write_header(run_header(agent, options, counters))
    if progress is not None:
        progress(counters)
    _play(
        agent,
        bench,
        header,
        [e for e in selection if e not in run.finished],
        options,
        run,
        progress,
        source,
    )

    rundir.rewrite_in_order(selection, run.finished, run.failures)
    final = run_header(agent, options, counters)
    rundir.write_header(final)
    kept = [run.failures[e] for e in selection if e in run.failures]
    return RunSummary(
        options.out,
        final,
        counters,
        kept,
        [*unread, *run.skipped],
        extended_from=_extended(before, counters),
    )


def _check_options(options: RunOptions) -> None:
    """The options' bounds; a price is what run.json may hold (PROTOCOL §1.4: a finite number
    of USD from 0 to `replay.semantics.MAX_PRICE`, so every cost is a number too)."""
    if options.concurrency < 1:
        raise RunDirError("--concurrency must be at least 1")
    if options.max_consecutive_failures < 0:
        raise RunDirError("--max-consecutive-failures must be 0 (never stop) or more")
    for option, price in (
        ("--prompt-price", options.prompt_price),
        ("--completion-price", options.completion_price),
    ):
        try:
            replay.semantics.run_prices({replay.semantics.PROMPT_PRICE_KEY: price})
        except ValueError:
            raise RunDirError(
                f"{option}: a price is a number of USD per million tokens from 0 to "
                f"{replay.semantics.MAX_PRICE:,.0f}, not {price!r}"
            ) from None


def _continuing(options: RunOptions) -> tuple[RunOptions, Source]:
    """A continuation run's source, and its options completed: the source's run id, and the
    source's λ (the cut and `source_success` are the source's replay under it; a run under
    another λ would not continue the same episodes)."""
    asked = options.continuation
    assert asked is not None
    where = Path(asked.source)
    if where.resolve() == options.out.resolve():
        raise RunDirError(f"--from {where}: a run cannot continue itself; choose another --out")
    run = SourceRun.open(where)
    lam = replay.run_lambda(run.header.lam)
    if options.lam is not None and options.lam != lam:
        raise RunDirError(
            f"--lambda {options.lam:g}: a continuation plays under its source's lambda "
            f"({lam:g}, {run_json_path(where)})"
        )
    asked = msgspec.structs.replace(asked, source=where, from_run=run.header.run_id)
    options = msgspec.structs.replace(options, lam=lam, continuation=asked)
    return options, Source(run, asked)


def _extended(before: replay.RunHeader | None, counters: Counters) -> int | None:
    was = before.meta.get("episodes_selected") if before is not None else None
    return was if isinstance(was, int) and was < counters.selected else None


def _play(
    agent: LiveAgent,
    bench: replay.Benchmark,
    header: replay.RunHeader,
    todo: list[str],
    options: RunOptions,
    run: _Run,
    progress: Callable[[Counters], None] | None,
    source: Source | None,
) -> None:
    """Play `todo` on `options.concurrency` threads, one episode each: the next one starts
    once the main thread has taken the last result, so a run that stops starts nothing more.
    On any exception, stop the threads, keep what they finished, and raise."""
    stop = threading.Event()
    local = threading.local()

    def play(episode_id: str) -> Outcome:
        worker = getattr(local, "worker", None)
        if worker is None:
            worker = local.worker = Worker(agent, bench, header, stop, source)
        return worker.play(episode_id)

    pool = ThreadPoolExecutor(max_workers=options.concurrency, thread_name_prefix="vge-run")
    running: set[Future] = set()
    queue: Iterator[str] = iter(todo)
    try:
        for episode_id in queue:
            running.add(pool.submit(play, episode_id))
            if len(running) >= options.concurrency:
                break
        while running:
            done, _ = wait(running, return_when=FIRST_COMPLETED)
            for future in done:
                running.discard(future)  # the ones left are taken when stopping
                result = future.result()
                run.take(result)
                if progress is not None:
                    progress(run.counters)
                if isinstance(result, Failed):
                    stopped = run.too_many_failures(result.record)
                    if stopped is not None:
                        raise stopped
                following = next(queue, None)
                if following is not None:
                    running.add(pool.submit(play, following))
    except BaseException as exc:
        stop.set()  # the workers leave their episodes at the next step or wait
        pool.shutdown(wait=True, cancel_futures=True)
        for future in running:  # what finished while stopping is kept
            if not future.cancelled() and future.exception() is None:
                run.take(future.result())
        run.rundir.write_header(run_header(agent, options, run.counters))
        if isinstance(exc, RequestRefusedError):
            raise RequestRefusedError(f"{exc}; {run.written()}", status=exc.status) from exc
        raise
    pool.shutdown(wait=True)


__all__ = ["Counters", "RunOptions", "RunSummary", "run_live", "select_episodes"]
