"""`vge run`: an agent plays episodes of a benchmark through `vge/Device-v0`, and the run
directory gets what `vge replay` reads.

Each episode is played by one worker thread with an environment of its own; the main thread
alone writes the run directory (`_rundir.py`). The log of a step holds the agent's response
and what the environment recorded for it (view, feedback kind, state), so the replay of the
run checks itself: zero divergent steps. An infrastructure failure (a model request that
still fails after its retries) ends its episode without a line: it goes to
`failures.jsonl` and `--resume` plays it again. Nothing in the files depends on the clock
unless the agent measures time (tokens, latency and timestamps of `openai:` agents).
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ThreadPoolExecutor, wait
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import msgspec

import replay
from replay.env import DeviceEnv, log_step_of, no_images

from .._errors import AgentError, InfrastructureError, RunDirError
from ..synth import image_source
from ._agents import AGENT_KINDS, EpisodeStart, LiveAgent
from ._rundir import FailureRecord, RunDir

TOTAL_KEYS = (
    "episodes",
    "infrastructure_failures",
    "tasks_skipped",
    "complete",
    "steps",
    "prompt_tokens",
    "completion_tokens",
    "latency_seconds",
    "cost_usd",
)
"""Keys of run.json's meta that count what the run did (the others are its settings)."""
CONNECTION_KEYS = ("base_url", "request_timeout_seconds", "retries")
"""Settings of how the model is reached, which `--resume` may change (a server on a new
address); every other setting must stay as the run was started."""


class RunOptions(msgspec.Struct, frozen=True):
    """Everything `vge run` was asked, besides the agent."""

    bench: Path
    out: Path
    run_id: str | None = None
    """None: the name of `out`."""
    model: str | None = None
    """None: the agent's own name for its model."""
    agent_kind: str | None = None
    """None: the agent's kind (openai: vlm, sim: the profile's, module: scripted)."""
    lam: float | None = None
    """The run's λ (None: 5); a task's own λ wins (PROTOCOL §3.5)."""
    episodes: tuple[str, ...] | None = None
    limit: int | None = None
    concurrency: int = 1
    resume: bool = False
    prompt_price: float | None = None
    """USD per million prompt tokens."""
    completion_price: float | None = None
    """USD per million completion tokens."""


@dataclass(slots=True)
class Counters:
    """What the run has done so far (the progress bar's figures)."""

    selected: int = 0
    finished: int = 0
    succeeded: int = 0
    failures: int = 0
    skipped: int = 0
    steps: int = 0
    prompt_tokens: int = 0
    completion_tokens: int = 0
    latency_seconds: float = 0.0
    has_usage: bool = False
    prices: tuple[float | None, float | None] = (None, None)

    @property
    def cost_usd(self) -> float | None:
        prompt_price, completion_price = self.prices
        if not self.has_usage or (prompt_price is None and completion_price is None):
            return None
        return (
            self.prompt_tokens * (prompt_price or 0.0)
            + self.completion_tokens * (completion_price or 0.0)
        ) / 1e6

    def add(self, log: replay.EpisodeLog, success: bool) -> None:
        self.finished += 1
        self.succeeded += success
        self.steps += len(log.steps)
        for s in log.steps:
            if s.prompt_tokens is not None or s.completion_tokens is not None:
                self.has_usage = True
            self.prompt_tokens += s.prompt_tokens or 0
            self.completion_tokens += s.completion_tokens or 0
            self.latency_seconds += s.latency_seconds or 0.0


@dataclass(frozen=True, slots=True)
class RunSummary:
    out: Path
    header: replay.RunHeader
    counters: Counters
    failures: list[FailureRecord]
    skipped: list[str] = field(default_factory=list)
    """Tasks that cannot be played, each with its reason."""

    @property
    def complete(self) -> bool:
        return not self.failures


@dataclass(frozen=True, slots=True)
class _Finished:
    episode_id: str
    line: bytes
    log: replay.EpisodeLog
    success: bool


@dataclass(frozen=True, slots=True)
class _Failed:
    record: FailureRecord


@dataclass(frozen=True, slots=True)
class _Skipped:
    episode_id: str
    reason: str


class _Stopped(Exception):
    """The run is being stopped (Ctrl-C or a fatal agent error): leave the episode unplayed."""


_encoder = msgspec.json.Encoder()


def select_episodes(
    bench: replay.Benchmark, episodes: Sequence[str] | None, limit: int | None
) -> list[str]:
    """The episodes to play, in order: those named (in the order given) or every task of
    `tasks.jsonl` (in file order), then the first `limit`."""
    if episodes is None:
        chosen = list(bench.tasks)
    else:
        chosen = list(dict.fromkeys(episodes))
        unknown = [e for e in chosen if e not in bench.tasks]
        if unknown:
            raise RunDirError(
                f"--episodes: not in {bench.tasks_path}: {', '.join(map(repr, unknown[:5]))}"
                + (f" and {len(unknown) - 5} more" if len(unknown) > 5 else "")
            )
    if limit is not None:
        chosen = chosen[:limit]
    return chosen


def run_header(
    agent: LiveAgent, options: RunOptions, selected: int, counters: Counters
) -> replay.RunHeader:
    agent_kind = options.agent_kind or agent.agent_kind
    if agent_kind not in AGENT_KINDS:
        raise RunDirError(f"--agent-kind must be one of {', '.join(AGENT_KINDS)}")
    meta: dict[str, Any] = dict(agent.settings())
    meta["episodes_selected"] = selected
    if options.prompt_price is not None:
        meta["prompt_price_per_mtok"] = options.prompt_price
    if options.completion_price is not None:
        meta["completion_price_per_mtok"] = options.completion_price
    meta |= {
        "episodes": counters.finished,
        "infrastructure_failures": counters.failures,
        "tasks_skipped": counters.skipped,
        "complete": counters.finished + counters.skipped == selected,
        "steps": counters.steps,
    }
    if counters.has_usage:
        meta["prompt_tokens"] = counters.prompt_tokens
        meta["completion_tokens"] = counters.completion_tokens
        meta["latency_seconds"] = round(counters.latency_seconds, 3)
        if counters.cost_usd is not None:
            meta["cost_usd"] = round(counters.cost_usd, 6)
    return replay.RunHeader(
        run_id=options.run_id or options.out.resolve().name,
        model=options.model or agent.model,
        agent_kind=agent_kind,  # type: ignore[arg-type]
        lam=replay.run_lambda(options.lam),
        meta=meta,
    )


def _settings(header: replay.RunHeader) -> dict[str, Any]:
    return {
        "run_id": header.run_id,
        "model": header.model,
        "agent_kind": header.agent_kind,
        "lambda": header.lam,
        **{
            k: v for k, v in header.meta.items() if k not in TOTAL_KEYS and k not in CONNECTION_KEYS
        },
    }


def _check_resume(old: replay.RunHeader, new: replay.RunHeader) -> None:
    before, now = _settings(old), _settings(new)
    changed = sorted(k for k in before.keys() | now.keys() if before.get(k) != now.get(k))
    if changed:
        said = "; ".join(f"{k}: {before.get(k)!r} then, {now.get(k)!r} now" for k in changed)
        raise RunDirError(f"--resume with other settings than the run was started with ({said})")


def _replayed_success(bench: replay.Benchmark, log: replay.EpisodeLog, lam: float | None) -> bool:
    """Whether a finished episode of an earlier attempt succeeded (its replay says)."""
    task = bench.tasks[log.episode_id].task
    session = replay.EpisodeSession(
        bench.machine(task.device_id),
        task,
        lam=replay.episode_lambda(task, lam),
        run_id="",
        model="",
        agent_kind="vlm",
    )
    for s in log.steps:
        session.advance(s)
    return session.termination == "success"


class _Worker:
    """Plays episodes on its own environment (one per thread)."""

    def __init__(
        self,
        agent: LiveAgent,
        bench: replay.Benchmark,
        header: replay.RunHeader,
        stop: threading.Event,
    ) -> None:
        self.agent = agent
        self.header = header
        self.stop = stop
        self.env = DeviceEnv(
            bench,
            lam=header.lam,
            image_source=image_source(bench.root) if agent.looks else no_images,
            run_id=header.run_id,
            model=header.model,
            agent_kind=header.agent_kind,
        )

    def play(self, episode_id: str) -> _Finished | _Failed | _Skipped:
        try:
            obs, _ = self.env.reset(options={"episode_id": episode_id})
        except replay.VGEError as exc:
            return _Skipped(episode_id, str(exc))
        player = self.agent.start(EpisodeStart(obs, self.env, self.header.run_id))
        steps: list[replay.LogStep] = []
        while True:
            if self.stop.is_set():
                raise _Stopped
            try:
                reply = player.act(obs)
            except InfrastructureError as exc:
                return _Failed(FailureRecord(episode_id, len(steps), str(exc)))
            except replay.VGEError:
                raise
            except Exception as exc:
                raise AgentError(
                    f"agent {self.agent.spec} raised {type(exc).__name__}: "
                    f"{' '.join(str(exc).split())} (episode {episode_id!r}, step {len(steps)})"
                ) from exc
            try:
                obs, _, terminated, truncated, info = self.env.step(reply.action)
            except replay.ActionError as exc:
                raise AgentError(
                    f"agent {self.agent.spec}: {exc} (episode {episode_id!r}, step {len(steps)})"
                ) from None
            steps.append(
                msgspec.structs.replace(
                    log_step_of(reply.action),
                    view=info["view_after"],
                    feedback=info["feedback_kind"],
                    state=info["state_after"],
                    timestamp=reply.timestamp,
                    prompt_tokens=reply.prompt_tokens,
                    completion_tokens=reply.completion_tokens,
                    latency_seconds=reply.latency_seconds,
                )
            )
            player.observe(obs, info)
            if terminated or truncated:
                break
        log = replay.EpisodeLog(episode_id=episode_id, steps=steps)
        return _Finished(episode_id, _episode_line(log), log, terminated)


def _episode_line(log: replay.EpisodeLog) -> bytes:
    """One line of the episodes file; fields left unset are left out."""
    steps = [
        {k: v for k, v in msgspec.structs.asdict(s).items() if v is not None} for s in log.steps
    ]
    return _encoder.encode({"episode_id": log.episode_id, "steps": steps}) + b"\n"


def run_live(
    agent: LiveAgent,
    options: RunOptions,
    progress: Callable[[Counters], None] | None = None,
) -> RunSummary:
    """Play the selected episodes (those not finished yet, with `resume`) and complete the
    run directory. Raises `AgentError` when the agent cannot go on (the episodes finished
    so far stay written: `--resume` continues)."""
    if options.concurrency < 1:
        raise RunDirError("--concurrency must be at least 1")
    options = msgspec.structs.replace(options, bench=Path(options.bench), out=Path(options.out))
    bench = replay.Benchmark.open(options.bench)
    selection = select_episodes(bench, options.episodes, options.limit)
    counters = Counters(selected=len(selection))
    counters.prices = (options.prompt_price, options.completion_price)
    rundir = RunDir(options.out)
    header = run_header(agent, options, len(selection), counters)
    finished: dict[str, bytes] = {}
    if options.resume:
        # Episodes that failed before are not finished: they are played again.
        _check_resume(rundir.read_header(), header)
        finished = rundir.finished()
        outside = [e for e in finished if e not in set(selection)]
        if outside:
            raise RunDirError(
                f"{rundir.episodes_path} holds episode {outside[0]!r}, which is not selected"
            )
        decoder = msgspec.json.Decoder(replay.EpisodeLog)
        for line in finished.values():
            log = decoder.decode(line)
            counters.add(log, _replayed_success(bench, log, header.lam))
    else:
        rundir.create()
    rundir.write_header(run_header(agent, options, len(selection), counters))
    todo = [e for e in selection if e not in finished]
    skipped: list[str] = []
    if progress is not None:
        progress(counters)

    stop = threading.Event()
    local = threading.local()

    def play(episode_id: str) -> _Finished | _Failed | _Skipped:
        worker = getattr(local, "worker", None)
        if worker is None:
            worker = local.worker = _Worker(agent, bench, header, stop)
        return worker.play(episode_id)

    latest_failures: dict[str, FailureRecord] = {}
    pool = ThreadPoolExecutor(max_workers=options.concurrency, thread_name_prefix="vge-run")
    try:
        queue = iter(todo)
        running: set[Future] = set()
        for episode_id in queue:
            running.add(pool.submit(play, episode_id))
            if len(running) >= 2 * options.concurrency:
                break
        while running:
            done, running = wait(running, return_when=FIRST_COMPLETED)
            for future in done:
                result = future.result()
                if isinstance(result, _Finished):
                    rundir.append(result.line)
                    finished[result.episode_id] = result.line
                    counters.add(result.log, result.success)
                elif isinstance(result, _Failed):
                    rundir.append_failure(result.record)
                    latest_failures[result.record.episode_id] = result.record
                    counters.failures += 1
                else:
                    skipped.append(f"{result.episode_id}: {result.reason}")
                    counters.skipped += 1
                if progress is not None:
                    progress(counters)
                following = next(queue, None)
                if following is not None:
                    running.add(pool.submit(play, following))
    except BaseException:
        stop.set()
        pool.shutdown(wait=True, cancel_futures=True)
        rundir.write_header(run_header(agent, options, len(selection), counters))
        raise
    pool.shutdown(wait=True)

    rundir.rewrite_in_order(selection, finished, latest_failures)
    final = run_header(agent, options, len(selection), counters)
    rundir.write_header(final)
    kept = [latest_failures[e] for e in selection if e in latest_failures]
    return RunSummary(options.out, final, counters, kept, skipped)


__all__ = ["TOTAL_KEYS", "Counters", "RunOptions", "RunSummary", "run_live", "select_episodes"]
