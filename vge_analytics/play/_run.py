"""The human run: a run directory written episode by episode as a person plays (see the
package docstring for the files and what a crash leaves)."""

from __future__ import annotations

import fcntl
import hashlib
import os
import re
import time
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import msgspec
import numpy as np
import orjson

import replay
from replay.env import DeviceEnv
from replay.io import (
    EPISODES,
    EPISODES_GZ,
    RUN_JSON,
    RunDirectory,
    append_record,
    fsync_dir,
    keep_aside,
    truncate,
    write_all,
)

from .._errors import PlayConflictError, PlayError
from ..synth import image_source as default_images
from ._clicks import action_text
from ._files import DEFAULT_RUN_DIR, journal_header, journal_steps

if TYPE_CHECKING:
    from replay import ImageSource

DEFAULT_MODEL = "human"
"""`model` of a human run unless `--model` names the participant or group."""
IMAGE_SIZE = 768
"""Side of the square image the environment renders each view at (the scale is relative to
width and height, so resizing keeps it exact)."""

JOURNAL_DIR = "playing"
DISCARDED_DIR = "discarded"
LOCK_FILE = ".lock"

Clock = Callable[[], float]


@dataclass(frozen=True)
class EpisodeStatus:
    """Where one task of the benchmark stands in the run."""

    episode_id: str
    device_id: str
    n_goals: int
    state: Literal["new", "unfinished", "finished"]
    steps: int
    """Steps played so far (unfinished) or in all (finished)."""

    def label(self) -> str:
        """How the episode picker shows it. Only what never changes: the picker does not
        redraw the label of the chosen episode while it is played."""
        return f"{self.episode_id} · {self.device_id} · {counted(self.n_goals, 'goal')}"

    def summary(self) -> str:
        """Where the episode stands, in words."""
        return {
            "new": "Not played in this run yet.",
            "unfinished": f"Unfinished: {counted(self.steps, 'step')} played so far.",
            "finished": f"Played to its end in {counted(self.steps, 'step')}.",
        }[self.state]


def counted(n: int, noun: str) -> str:
    return f"{n} {noun}" + ("" if n == 1 else "s")


@dataclass(frozen=True)
class StepRecord:
    """One step as the page shows it after it was written."""

    index: int
    action: str
    feedback: str
    feedback_kind: str


class HumanRun:
    """A run directory written by hand, episode by episode (see the module docstring).

    `open` creates it (run.json with `agent_kind: "human"`, an empty episodes file) or opens
    an existing human run, repairing what a crash may have left. `clock` gives each step's
    `timestamp` (seconds since the epoch): the only wall-clock value in the run, kept for
    analyses of how long people take; `None` records no time at all.
    """

    def __init__(
        self,
        root: Path,
        bench: replay.Benchmark,
        header: replay.RunHeader,
        *,
        clock: Clock | None,
        image_source: ImageSource | None,
        image_size: tuple[int, int],
    ) -> None:
        self.root = root
        self.files = RunDirectory(root, aside=root / JOURNAL_DIR / DISCARDED_DIR)
        """The run.json and episodes file, written by the replay's one writer."""
        self.bench = bench
        self.header = header
        self.clock = clock
        self.image_source = image_source
        """Where the views come from (None: the benchmark's images and rendered views)."""
        self.image_size = image_size
        """(width, height) the environment renders each view at."""

    # ------------------------------------------------------------------ opening

    @classmethod
    def open(
        cls,
        root: str | Path,
        bench: str | Path | replay.Benchmark,
        *,
        run_id: str | None = None,
        model: str | None = None,
        lam: float | None = None,
        clock: Clock | None = time.time,
        image_source: ImageSource | None = None,
        image_size: tuple[int, int] = (IMAGE_SIZE, IMAGE_SIZE),
    ) -> HumanRun:
        """Create the run at `root` or open it. `run_id` (default: the directory's name),
        `model` (default `human`) and `lam` are written when the run is created; given for
        an existing run, they must match its run.json. `image_source` and `image_size` are
        the environment's (`replay.env.DeviceEnv`)."""
        root = Path(root)
        if not isinstance(bench, replay.Benchmark):
            bench = replay.Benchmark.open(bench)
        if root.exists() and not root.is_dir():
            raise PlayError(f"{root} exists and is not a directory")
        header_path = root / RUN_JSON
        if header_path.exists():
            header = replay.read_run_header(root)
            if header.agent_kind != "human":
                raise PlayError(
                    f"{root} is a run of agent kind {header.agent_kind!r}: `vge play` writes "
                    "human runs only (give another --out)"
                )
            asked = {"run_id": run_id, "model": model, "lambda": lam}
            have = {"run_id": header.run_id, "model": header.model, "lambda": header.lam}
            for key, value in asked.items():
                if value is not None and value != have[key]:
                    raise PlayError(
                        f"{header_path} has {key} {have[key]!r}, not {value!r}: a run keeps "
                        "the settings it was created with (give another --out)"
                    )
            if (root / EPISODES_GZ).exists():
                raise PlayError(
                    f"{root} holds {EPISODES_GZ}: `vge play` appends to a plain "
                    f"{EPISODES} (give another --out)"
                )
        else:
            root.mkdir(parents=True, exist_ok=True)
            header = replay.RunHeader(
                run_id=run_id or root.resolve().name,
                model=model or DEFAULT_MODEL,
                agent_kind="human",
                lam=None if lam is None else float(lam),
                meta={"interface": "vge play"},
            )
            RunDirectory(root).write_header(header)
        (root / EPISODES).touch()
        (root / JOURNAL_DIR).mkdir(exist_ok=True)
        run = cls(
            root, bench, header, clock=clock, image_source=image_source, image_size=image_size
        )
        with run.locked():
            run._repair()
        return run

    @contextmanager
    def locked(self) -> Iterator[None]:
        """The run's write lock (between threads and between processes)."""
        with open(self.root / JOURNAL_DIR / LOCK_FILE, "a+b") as fh:
            fcntl.flock(fh.fileno(), fcntl.LOCK_EX)
            try:
                yield
            finally:
                fcntl.flock(fh.fileno(), fcntl.LOCK_UN)

    def _repair(self) -> None:
        """Undo what a crash in the middle of a write left (caller holds the lock)."""
        self.files.repair()  # a torn episode line: its journal still holds these steps
        finished = self._finished_logs()
        for path in sorted((self.root / JOURNAL_DIR).glob("*.jsonl")):
            episode_id = journal_header(path)
            if episode_id is None and b"\n" not in path.read_bytes():
                path.unlink()  # the first write was torn: no step of it was ever shown
            elif episode_id in finished:
                path.unlink()  # ended, but the app died before removing it

    # ------------------------------------------------------------------ reading

    @property
    def episodes_path(self) -> Path:
        return self.files.episodes_path

    def _finished_logs(self) -> dict[str, list[dict]]:
        """{episode id: its steps} of the episodes file (its lines are episode records)."""
        return {
            episode_id: list(orjson.loads(line).get("steps") or [])
            for episode_id, line in self.files.finished().items()
        }

    def _journals(self) -> dict[str, Path]:
        """{episode id: journal path} of the episodes being played."""
        out = {}
        for path in sorted((self.root / JOURNAL_DIR).glob("*.jsonl")):
            header = journal_header(path)
            if header is not None:
                out[header] = path
        return out

    def journal_path(self, episode_id: str) -> Path:
        """`playing/<readable id>.<hash>.jsonl`: any episode id makes a safe, unique name."""
        readable = re.sub(r"[^A-Za-z0-9._-]+", "_", episode_id)[:80]
        digest = hashlib.sha256(episode_id.encode()).hexdigest()[:10]
        return self.root / JOURNAL_DIR / f"{readable}.{digest}.jsonl"

    def statuses(self) -> list[EpisodeStatus]:
        """Every task of the benchmark, in tasks.jsonl order, with where it stands."""
        finished = self._finished_logs()
        journals = self._journals()
        out = []
        for episode_id, entry in self.bench.tasks.items():
            task = entry.task
            if episode_id in finished:
                state, steps = "finished", len(finished[episode_id])
            elif episode_id in journals:
                try:
                    steps = len(journal_steps(journals[episode_id])[0])
                except PlayError:
                    steps = 0  # resuming says what is wrong; discarding is offered
                state = "unfinished"
            else:
                state, steps = "new", 0
            out.append(EpisodeStatus(episode_id, task.device_id, len(task.goals), state, steps))
        return out

    def status(self, episode_id: str) -> EpisodeStatus:
        for s in self.statuses():
            if s.episode_id == episode_id:
                return s
        raise PlayError(f"episode {episode_id!r} is not in {self.bench.tasks_path}")

    def next_episode(self, after: str | None = None) -> str | None:
        """The first episode (after `after`, in tasks.jsonl order) not finished in this run
        that can be played; None when every one is."""
        ids = [s.episode_id for s in self.statuses() if s.state != "finished"]
        if after is not None and after in self.bench.tasks:
            position = {e: i for i, e in enumerate(self.bench.tasks)}
            start = position[after]
            ids.sort(key=lambda e: (position[e] <= start, position[e]))
        for episode_id in ids:
            if self.playable(episode_id):
                return episode_id
        return None

    def playable(self, episode_id: str) -> bool:
        """The task's device loads and its goals can be planned (PROTOCOL §4)."""
        task = self.bench.tasks[episode_id].task
        try:
            replay.semantics.setup_episode(self.bench.machine(task.device_id), task)
        except replay.VGEError:
            return False
        return True

    def result(self, episode_id: str) -> replay.EpisodeRow:
        """The replay's episode row of a finished episode (success, SPL, ...)."""
        steps = self._finished_logs().get(episode_id)
        if steps is None:
            raise PlayError(f"episode {episode_id!r} has not been played to its end in this run")
        task = self.bench.tasks[episode_id].task
        log = msgspec.convert({"episode_id": episode_id, "steps": steps}, replay.EpisodeLog)
        return replay.replay_episode(
            self.bench.machine(task.device_id),
            task,
            log,
            lam=replay.episode_lambda(task, self.header.lam),
            run_id=self.header.run_id,
            model=self.header.model,
            agent_kind=self.header.agent_kind,
        ).episode

    # ------------------------------------------------------------------ playing

    def start(self, episode_id: str) -> EpisodePlay:
        """A new episode. Refused when it was finished in this run (each episode is played
        once per run) or has an unfinished journal (resume or discard it first)."""
        status = self.status(episode_id)
        if status.state == "finished":
            raise PlayError(f"episode {episode_id!r} was already played in this run")
        if status.state == "unfinished":
            raise PlayError(
                f"episode {episode_id!r} has {status.steps} unfinished steps: resume or discard "
                "them first"
            )
        return EpisodePlay(self, episode_id)

    def resume(self, episode_id: str) -> EpisodePlay:
        """The unfinished episode, its journal's steps played again through the environment
        (a torn last line, a step whose feedback was never shown, is cut off first). An
        episode whose last journalled step had ended it is finished at once."""
        with self.locked():
            path = self._journals().get(episode_id)
            if path is None:
                raise PlayError(f"episode {episode_id!r} has no unfinished steps to resume")
            steps, good_size = journal_steps(path)
            if path.stat().st_size != good_size:
                truncate(path, good_size)
        play = EpisodePlay(self, episode_id)
        play._replay_journal(path, steps)
        return play

    def discard(self, episode_id: str) -> Path:
        """Move the unfinished episode's journal to `playing/discarded/` (kept, never read
        by the replay); returns where it went."""
        with self.locked():
            path = self._journals().get(episode_id)
            if path is None:
                raise PlayError(f"episode {episode_id!r} has no unfinished steps to discard")
            target = keep_aside(path.parent / DISCARDED_DIR, path.stem, path.read_bytes())
            path.unlink()
            fsync_dir(path.parent)
            return target

    def _append_episode(self, episode_id: str, steps: list[dict]) -> None:
        """Append the finished episode's line (caller holds the lock)."""
        if episode_id in self._finished_logs():
            raise PlayConflictError(
                f"episode {episode_id!r} was ended in another window; it is already in the run"
            )
        self._repair()
        self.files.append(orjson.dumps({"episode_id": episode_id, "steps": steps}) + b"\n")


class EpisodePlay:
    """One episode being played: the environment, and its journal on disk.

    `act(action)` takes one step (a structured action, `action()`), writes it to the
    journal and returns the environment's step info (a row of the steps table). When the
    episode terminates (success, or a budget ran out) or the person ends it (`end()`), its
    line goes to the episodes file.
    """

    def __init__(self, run: HumanRun, episode_id: str) -> None:
        self.run = run
        self.episode_id = episode_id
        header = run.header
        self.env = DeviceEnv(
            run.bench,
            lam=header.lam,
            image_width=run.image_size[0],
            image_height=run.image_size[1],
            image_source=run.image_source or default_images(run.bench.root),
            run_id=header.run_id,
            model=header.model,
            agent_kind=header.agent_kind,
        )
        self.observation, self.reset_info = self.env.reset(options={"episode_id": episode_id})
        self.journal = run.journal_path(episode_id)
        self.steps: list[dict] = []
        """The log steps written so far (as in the journal and the episode line)."""
        self.records: list[StepRecord] = []
        self.result: replay.EpisodeRow | None = None
        """The episode's row once it has ended."""
        self._journal_size: int | None = None  # None: not created yet
        self._failed = False

    # ------------------------------------------------------------------ state

    @property
    def done(self) -> bool:
        return self.result is not None

    @property
    def image(self) -> np.ndarray:
        """The current view (uint8, `IMAGE_SIZE` square)."""
        return self.observation["image"]

    @property
    def broken(self) -> bool:
        """A step was taken but could not be written: the episode must be resumed from its
        journal."""
        return self._failed

    @property
    def last(self) -> StepRecord | None:
        return self.records[-1] if self.records else None

    # ------------------------------------------------------------------ acting

    def act(self, action: Mapping[str, Any]) -> dict[str, Any]:
        """Play one step and write it to the journal before returning its info."""
        if self.done:
            raise PlayError(f"episode {self.episode_id!r} has ended; pick the next one")
        if self._failed:
            raise PlayError(f"episode {self.episode_id!r}: a step could not be saved; resume it")
        with self.run.locked():
            self._check_journal()
            observation, _, terminated, truncated, info = self.env.step(dict(action))
            step = self._log_step(action, info)
            try:
                self._write_step(step)
            except BaseException:
                self._failed = True  # the environment is a step ahead of the journal
                raise
        self._took(step, info, observation)
        if terminated or truncated:
            self._finish()
        return info

    def _write_step(self, step: dict) -> None:
        line = orjson.dumps(step) + b"\n"
        if self._journal_size is not None:
            append_record(self.journal, line)
            self._journal_size += len(line)
            return
        # The first step creates the journal, its header and the step in one write.
        data = orjson.dumps({"episode_id": self.episode_id}) + b"\n" + line
        try:
            fd = os.open(self.journal, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
        except FileExistsError:
            raise PlayConflictError(
                f"episode {self.episode_id!r} was started in another window: resume it from "
                "the episode picker"
            ) from None
        try:
            write_all(fd, data)
        finally:
            os.close(fd)
        fsync_dir(self.journal.parent)
        self._journal_size = len(data)

    def end(self) -> replay.EpisodeRow | None:
        """End the episode here (the person gives up: `log_ended`). An episode with no step
        leaves nothing in the run and returns None."""
        if self.done:
            return self.result
        if not self.steps:
            return None
        self._finish()
        return self.result

    # ------------------------------------------------------------------ internals

    def _log_step(self, action: Mapping[str, Any], info: Mapping[str, Any]) -> dict:
        """The log step: the action, and what the environment answered (PROTOCOL §1.4) so
        that the replay checks it (divergence). The feedback kind is recorded rather than
        its text: kinds are the protocol, texts may be reworded."""
        step: dict[str, Any] = {
            "action": {
                "type": action["type"],
                "coord": action.get("coord"),
                "params": list(action.get("params") or []),
            },
            "view": info["view_after"],
            "feedback": info["feedback_kind"],
            "state": info["state_after"],
        }
        if self.run.clock is not None:
            step["timestamp"] = round(self.run.clock(), 3)
        return step

    def _took(self, step: dict, info: Mapping[str, Any], observation: dict) -> None:
        self.steps.append(step)
        self.records.append(
            StepRecord(
                len(self.records), action_text(step), info["feedback_text"], info["feedback_kind"]
            )
        )
        self.observation = observation

    def _check_journal(self) -> None:
        """Refuse to write when another window changed the journal since this one wrote."""
        try:
            size = self.journal.stat().st_size
        except FileNotFoundError:
            size = None
        if size != self._journal_size:
            raise PlayConflictError(
                f"episode {self.episode_id!r} was changed in another window (played on, "
                "ended or discarded): open it again from the episode picker"
            )

    def _replay_journal(self, path: Path, steps: list[dict]) -> None:
        """Play the journal's steps again; each must give what was recorded."""
        for k, step in enumerate(steps):
            observation, _, terminated, truncated, info = self.env.step(step["action"])
            got = {"view": info["view_after"], "feedback": info["feedback_kind"]}
            got["state"] = info["state_after"]
            wrong = [key for key, value in got.items() if step.get(key) != value]
            if wrong:
                raise PlayError(
                    f"episode {self.episode_id!r} cannot be resumed: step {k} of its journal "
                    f"now gives another {' and '.join(wrong)} (the benchmark changed?); "
                    "discard it"
                )
            self._took(step, info, observation)
            if (terminated or truncated) and k != len(steps) - 1:
                raise PlayError(
                    f"episode {self.episode_id!r} cannot be resumed: its journal goes on after "
                    f"the episode ended at step {k}; discard it"
                )
        self._journal_size = path.stat().st_size
        if self.env.session is not None and self.env.session.done:
            self._finish()  # the app died between the last step and the episode line

    def _finish(self) -> None:
        with self.run.locked():
            self._check_journal()
            self.run._append_episode(self.episode_id, self.steps)
            self.journal.unlink()
            fsync_dir(self.journal.parent)
        session = self.env.session
        assert session is not None
        self.result = session.finish().episode


__all__ = [
    "DEFAULT_MODEL",
    "DEFAULT_RUN_DIR",
    "IMAGE_SIZE",
    "EpisodePlay",
    "EpisodeStatus",
    "HumanRun",
    "StepRecord",
]
