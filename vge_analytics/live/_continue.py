"""Continuation runs (`vge run --from RUN_DIR --at K|first-error [--fix]`, PROTOCOL §10.4):
where each episode of the source run is cut, what is replayed of it, and the fix.

The source's episode is replayed first (the session the replay uses, under the source run's
λ): that gives its first error (the first scored step with an error type, PROTOCOL §5.2),
its success and whether its steps reached a termination. The cut follows from them, and so
does the planner's step at the cut (PROTOCOL §4.5): the same deterministic situation the
live episode reaches after the same steps.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import msgspec

import replay

from .._errors import RunDirError

FIRST_ERROR = "first-error"
"""`--at first-error`: cut every episode before its first error."""

_ERROR_TYPE = replay.StepRow.__struct_fields__.index("error_type")
_decoder = msgspec.json.Decoder(replay.EpisodeLog)


def parse_at(text: str) -> int | str:
    """`--at`: a number of steps (0 or more) or `first-error`."""
    if text == FIRST_ERROR:
        return FIRST_ERROR
    if text.isdigit():
        return int(text)
    raise RunDirError(f"--at takes a number of steps or {FIRST_ERROR}, not {text!r}")


def continuation_of(source: Path | None, at: str | None, fix: bool) -> ContinueFrom | None:
    """`--from`, `--at` and `--fix` as given: a continuation, or None for an ordinary run;
    `--at` and `--fix` without `--from`, or `--from` without `--at`, are refused."""
    if source is None:
        if at is not None or fix:
            raise RunDirError("--at and --fix continue another run: they need --from RUN_DIR")
        return None
    if at is None:
        raise RunDirError(f"--from {source}: say where to cut with --at K or --at {FIRST_ERROR}")
    return ContinueFrom(source=source, at=parse_at(at), fix=fix)


class ContinueFrom(msgspec.Struct, frozen=True, kw_only=True):
    """What `--from`, `--at` and `--fix` ask for."""

    source: Path
    """The source run directory."""
    at: int | str
    """Steps replayed before the cut, or `first-error`."""
    fix: bool = False
    """Play the planner's optimal step at the cut before the agent."""
    from_run: str = ""
    """The source's run id (filled once its run.json is read)."""

    def meta(self) -> dict[str, Any]:
        """run.json's `meta.counterfactual` (PROTOCOL §10.4)."""
        return {"from_run": self.from_run, "at": self.at, "fix": self.fix}


UNREAD_SHOWN = 10
"""Source lines that are not episode records named one by one; the rest are counted."""


@dataclass(frozen=True, slots=True)
class SourceRun:
    """The source run: its header, and each episode's line (file order, the first line of an
    id wins, as in a replay)."""

    root: Path
    header: replay.RunHeader
    lines: dict[str, bytes]
    unread: tuple[str, ...] = ()
    """The source's lines that are not episode records (the replay quarantines them), one
    line each naming the file and the line (the first `UNREAD_SHOWN`, then how many more):
    episodes that cannot be continued."""
    unread_count: int = 0

    @classmethod
    def open(cls, run_dir: Path) -> SourceRun:
        if not run_dir.is_dir():
            raise RunDirError(f"--from {run_dir}: not a run directory")
        header = replay.read_run_header(run_dir)
        lines: dict[str, bytes] = {}
        unread: list[str] = []
        count = 0
        path = replay.episodes_file(run_dir)
        for number, line in replay.io.iter_lines(path):
            try:
                episode_id = _decoder.decode(line).episode_id
            except (msgspec.DecodeError, UnicodeDecodeError) as exc:  # the replay's verdict
                count += 1
                if count <= UNREAD_SHOWN:
                    unread.append(
                        f"{path} line {number}: not an episode record, not continued ({exc})"
                    )
                continue
            lines.setdefault(episode_id, line)
        if count > UNREAD_SHOWN:
            more = count - UNREAD_SHOWN
            unread.append(f"{path}: {more:,} more lines that are not episode records")
        return cls(run_dir, header, lines, tuple(unread), count)

    def log(self, episode_id: str) -> replay.EpisodeLog:
        return _decoder.decode(self.lines[episode_id])  # read once already (`open`)


@dataclass(frozen=True, slots=True)
class Cut:
    """How one episode of the continuation starts."""

    steps: tuple[replay.LogStep, ...]
    """The source's steps to play first (the prefix, or the whole log for a copy), without
    what the source recorded or measured: the continuation records its own values."""
    fix: dict[str, Any] | None
    """The planner's step at the cut, as a structured action; None without one."""
    continuation: replay.Continuation
    ended: str | None
    """A copy keeps the source's `ended`; a continued episode ends on its own."""


def cut_episode(
    bench: replay.Benchmark,
    source: replay.RunHeader,
    log: replay.EpisodeLog,
    at: int | str,
    fix: bool,
) -> Cut:
    """Where the episode `log` of the source run is cut (PROTOCOL §10.4). Raises
    `replay.VGEError` when its task cannot be played."""
    entry = bench.tasks.get(log.episode_id)
    if entry is None:
        raise RunDirError(f"episode {log.episode_id!r} is not in {bench.tasks_path}")
    task = entry.task
    machine = bench.machine(task.device_id)
    lam = replay.episode_lambda(task, source.lam)

    def session() -> replay.EpisodeSession:
        return replay.EpisodeSession(
            machine, task, lam=lam, run_id=source.run_id, model=source.model,
            agent_kind=source.agent_kind,
        )  # fmt: skip

    whole = session()
    first_error: int | None = None
    for k, step in enumerate(log.steps):
        if whole.done:
            break
        if whole.advance(step)[_ERROR_TYPE] is not None and first_error is None:
            first_error = k
    terminated = whole.done  # by the rules, before the log ran out
    success = whole.termination == replay.semantics.SUCCESS
    n = len(log.steps)
    if at == FIRST_ERROR:
        prefix = first_error
    else:
        assert isinstance(at, int)
        prefix = None if terminated and whole.budget.taken <= at else min(at, n)
    bare = tuple(replay.LogStep(output=s.output, action=s.action) for s in log.steps)
    if prefix is None:  # nothing to cut at: the source's episode as it was
        return Cut(bare, None, replay.Continuation(n, False, False, success), log.ended)
    action = None
    if fix:  # the planner's step from where the prefix leaves the device
        cut = session()
        for step in log.steps[:prefix]:
            cut.advance(step)
        sim = cut.sim
        planned = replay.next_optimal_step(
            machine, sim.state, sim.view, sim.unlocked, tuple(cut.goals[cut.current :])
        )
        if planned is not None:
            a = planned.action
            action = {
                "type": replay.DISPLAY_NAMES[a.type],
                "coord": None if a.coord is None else list(a.coord),
                "params": list(a.params),
            }
    continuation = replay.Continuation(prefix, action is not None, True, success)
    return Cut(bare[:prefix], action, continuation, None)


@dataclass(frozen=True, slots=True)
class Source:
    """What a worker of a continuation run needs: the source run and where to cut."""

    run: SourceRun
    asked: ContinueFrom

    def cut(self, bench: replay.Benchmark, episode_id: str) -> Cut:
        return cut_episode(
            bench, self.run.header, self.run.log(episode_id), self.asked.at, self.asked.fix
        )


__all__ = [
    "FIRST_ERROR",
    "ContinueFrom",
    "continuation_of",
    "Cut",
    "Source",
    "SourceRun",
    "cut_episode",
    "parse_at",
]
