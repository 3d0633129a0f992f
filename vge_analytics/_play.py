"""Playing a benchmark by hand: the click mapping and the human run behind the Play page.

`vge play BENCH --out RUN` serves the Play page (`app/views/play.py`), which is a thin layer
over this module. The game is `replay.env.DeviceEnv` (`vge/Device-v0`), itself a wrapper
over `replay.EpisodeSession`, the object the replay drives: a played episode and the replay
of its log cannot disagree.

The run directory is one `vge replay` reads (PROTOCOL §1.4):

    RUN/run.json                  agent_kind "human", written when the run is created
    RUN/episodes.jsonl            one line per finished episode, structured actions
    RUN/playing/<episode>.jsonl   the journal of an episode being played (not read by replay)
    RUN/playing/discarded/        journals a person chose to throw away, torn lines cut off
                                  the episodes file (kept, never read)

Crash safety. Each step is appended to the episode's journal (one `write`, then `fsync`)
before the page shows its feedback, so a step a person has seen is on disk. When the episode
ends, its whole line is appended to `episodes.jsonl` the same way, and only then is the
journal removed. If the app dies:
- mid-step: the journal's last line may be torn; it is cut off when the episode is resumed
  (that step's feedback was never shown);
- mid-episode: the journal stays; the page offers to resume the episode (its steps are
  played again through the environment, which must give the feedback, state and view the
  journal recorded) or to discard it (the journal is moved to `playing/discarded/`);
- while ending an episode: a torn last line of `episodes.jsonl` is cut off when the run is
  opened (the journal, still there, holds the same steps; the torn bytes are kept in
  `playing/discarded/`), and a journal whose episode line is complete is removed.

Several browser tabs may play the same run: writes take a lock on the run, and a journal
that changed since a tab last wrote to it (another tab played on) is refused with a message
rather than interleaved.
"""

from __future__ import annotations

import fcntl
import hashlib
import math
import os
import re
import time
from collections.abc import Callable, Iterator, Mapping, MutableMapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import msgspec
import numpy as np
import orjson

import replay
from replay.env import DeviceEnv, episode_lambda

if TYPE_CHECKING:
    from replay import ImageSource

from ._errors import PlayConflictError, PlayError

SCALE = 1000
"""The agent's coordinate scale: 0..1000 on both axes of a view (PROTOCOL §1.2)."""
DEFAULT_MODEL = "human"
"""`model` of a human run unless `--model` names the participant or group."""
DEFAULT_RUN_DIR = "human-run"
"""Where `vge play` writes without `--out`."""
IMAGE_SIZE = 768
"""Side of the square image the environment renders each view at (the scale is relative to
width and height, so resizing keeps it exact)."""

EPISODES_FILE = "episodes.jsonl"
JOURNAL_DIR = "playing"
DISCARDED_DIR = "discarded"
LOCK_FILE = ".lock"

DASHBOARD = "dashboard"
"""The view a large device's control panel is zoomed in on, locked at first (PROTOCOL §3.1)."""
INTERACTIONS = ("Press", "Rotate", "Push", "Pull", "Grasp")
CLICK_ACTIONS = (*INTERACTIONS, "Switch_view")
"""What a click on the image can do (a `Switch_view` with a point unlocks the dashboard
when the point is on its panel, PROTOCOL §3.2)."""

PARAM_HINTS: dict[str, tuple[str, str]] = {
    "Press": ("0", "0: a short press, 1: press and hold, 2: double press"),
    "Rotate": ("0, 1", "direction (0: clockwise, 1: counter-clockwise), then steps; * for any"),
    "Push": ("4", "direction: 0 up, 1 down, 2 left, 3 right, 4 in"),
    "Pull": ("4", "direction: 0 up, 1 down, 2 left, 3 right, 4 out"),
    "Grasp": ("0", "0: pick up, 1: let go"),
}
"""Default parameters of each interaction as the page pre-fills them, with what they mean
(the conventions of the paper's action space; the device decides what it accepts)."""

FEEDBACK_TONES: dict[str, Literal["success", "warning", "error"]] = {
    "transition": "success",
    "view_switched": "success",
    "dashboard_unlocked": "success",
    "wait_no_effect": "warning",
    "null_effect": "warning",
    "operational_error": "warning",
    "invalid_action": "error",
}
"""How the page colours a step's feedback, by kind (PROTOCOL §3.6)."""

Clock = Callable[[], float]


# ----------------------------------------------------------------------- click mapping


def scale_coordinate(offset: float, displayed: float) -> int:
    """A pixel offset along an axis of the displayed image -> that axis of the 0..1000 scale.

    The rule is PROTOCOL §1.2's for boxes, `1000 * offset / displayed`, on the size the image
    is displayed at (never its natural size), rounded to the nearest integer with halves
    rounded up, then kept within 0..1000. Computed in exact fractions, so 0.5 really rounds
    up. A whole number keeps the log readable and loses at most half a unit, less than one
    displayed pixel whenever the image is shown at most 1000 pixels wide.
    """
    if not displayed > 0 or not math.isfinite(displayed):
        raise PlayError(f"the image's displayed size must be positive, not {displayed!r}")
    if not math.isfinite(offset):
        raise PlayError(f"a click's offset must be a number, not {offset!r}")
    value = Fraction(offset) * SCALE / Fraction(displayed)
    return min(max(math.floor(value + Fraction(1, 2)), 0), SCALE)


def click_point(click: Mapping[str, Any]) -> tuple[int, int]:
    """The 0..1000 point of a click as `streamlit-image-coordinates` reports it: `x`, `y`
    (offsets from the image's top-left corner) and `width`, `height` (its displayed size)."""
    try:
        x, y, width, height = (float(click[k]) for k in ("x", "y", "width", "height"))
    except (KeyError, TypeError, ValueError):
        raise PlayError(f"not a click on the image: {dict(click)!r}") from None
    return scale_coordinate(x, width), scale_coordinate(y, height)


def click_id(click: Mapping[str, Any] | None) -> tuple | None:
    """What tells one click from the next (the component reports its last click again on
    every rerun of the page; `PlayState.click` acts on each one once)."""
    if not click:
        return None
    return (click.get("unix_time"), click.get("x"), click.get("y"))


# ----------------------------------------------------------------------------- actions


def parse_params(text: str) -> list[str]:
    """Parameters typed as `a, b`: split on commas, blanks dropped (the engine normalises
    each value, PROTOCOL §1.2)."""
    return [p.strip() for p in text.split(",") if p.strip()]


def action(
    type_: str, coord: Sequence[float] | None = None, params: Sequence[Any] = ()
) -> dict[str, Any]:
    """A structured action as a human log carries it: `{"type", "coord", "params"}`."""
    return {
        "type": type_,
        "coord": None if coord is None else [coord[0], coord[1]],
        "params": list(params),
    }


def click_action(type_: str, point: tuple[int, int], params_text: str, view: str) -> dict:
    """The action a click at `point` carries out: an interaction with the typed parameters,
    or a `Switch_view` to `view` with the point (how the dashboard is unlocked)."""
    if type_ == "Switch_view":
        return action("Switch_view", point, [view])
    if type_ not in INTERACTIONS:
        raise PlayError(f"a click cannot carry out {type_!r}; one of {', '.join(CLICK_ACTIONS)}")
    return action(type_, point, parse_params(params_text))


def action_text(step: Mapping[str, Any]) -> str:
    """How a logged action reads: `Press(coord=[500, 250], params=[0])`."""
    a = step["action"]
    params = ", ".join(str(p) for p in a.get("params") or [])
    coord = a.get("coord")
    inner = (f"coord=[{coord[0]:g}, {coord[1]:g}], " if coord is not None else "") + (
        f"params=[{params}]"
    )
    return f"{a['type']}({inner})"


# ---------------------------------------------------------------------------- the run


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
        return f"{self.episode_id} · {self.device_id} · {_count(self.n_goals, 'goal')}"

    def summary(self) -> str:
        """Where the episode stands, in words."""
        return {
            "new": "Not played in this run yet.",
            "unfinished": f"Unfinished: {_count(self.steps, 'step')} played so far.",
            "finished": f"Played to its end in {_count(self.steps, 'step')}.",
        }[self.state]


def _count(n: int, noun: str) -> str:
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
        header_path = root / "run.json"
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
            if (root / f"{EPISODES_FILE}.gz").exists():
                raise PlayError(
                    f"{root} holds {EPISODES_FILE}.gz: `vge play` appends to a plain "
                    f"{EPISODES_FILE} (give another --out)"
                )
        else:
            root.mkdir(parents=True, exist_ok=True)
            document: dict[str, Any] = {
                "run_id": run_id or root.resolve().name,
                "model": model or DEFAULT_MODEL,
                "agent_kind": "human",
            }
            if lam is not None:
                document["lambda"] = float(lam)
            document["meta"] = {"interface": "vge play"}
            _write_new(header_path, orjson.dumps(document, option=orjson.OPT_INDENT_2) + b"\n")
            header = replay.read_run_header(root)
        (root / EPISODES_FILE).touch()
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
        path = self.episodes_path
        data = path.read_bytes()
        if data and not data.endswith(b"\n"):
            start = data.rfind(b"\n") + 1
            try:
                msgspec.json.decode(data[start:], type=replay.EpisodeLog)
                tail = b"\n"  # a complete line that only lacks its newline (hand-written)
            except msgspec.DecodeError:
                tail = None  # torn by a crash: its journal still holds these steps
                self._set_aside(data[start:], "episodes-tail")
            with open(path, "r+b") as fh:
                if tail is None:
                    fh.truncate(start)
                else:
                    fh.seek(0, os.SEEK_END)
                    fh.write(tail)
                fh.flush()
                os.fsync(fh.fileno())
        finished = self._finished_logs()
        for path in sorted((self.root / JOURNAL_DIR).glob("*.jsonl")):
            episode_id = _journal_header(path)
            if episode_id is None and b"\n" not in path.read_bytes():
                path.unlink()  # the first write was torn: no step of it was ever shown
            elif episode_id in finished:
                path.unlink()  # ended, but the app died before removing it

    def _set_aside(self, data: bytes, stem: str) -> Path:
        """Keep `data` in `playing/discarded/<stem>.<n>.jsonl` (never read again)."""
        folder = self.root / JOURNAL_DIR / DISCARDED_DIR
        folder.mkdir(exist_ok=True)
        n = 1
        while (target := folder / f"{stem}.{n}.jsonl").exists():
            n += 1
        _write_new(target, data)
        return target

    # ------------------------------------------------------------------ reading

    @property
    def episodes_path(self) -> Path:
        return self.root / EPISODES_FILE

    def _finished_logs(self) -> dict[str, list[dict]]:
        """{episode id: its steps} of the complete lines of the episodes file."""
        out: dict[str, list[dict]] = {}
        for raw in self.episodes_path.read_bytes().split(b"\n"):
            try:
                line = orjson.loads(raw)
            except orjson.JSONDecodeError:
                continue  # blank, or a torn tail not yet repaired
            if isinstance(line, dict) and isinstance(line.get("episode_id"), str):
                out.setdefault(line["episode_id"], list(line.get("steps") or []))
        return out

    def _journals(self) -> dict[str, Path]:
        """{episode id: journal path} of the episodes being played."""
        out = {}
        for path in sorted((self.root / JOURNAL_DIR).glob("*.jsonl")):
            header = _journal_header(path)
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
                    steps = len(_journal_steps(journals[episode_id])[0])
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
            replay.setup_episode(self.bench.machine(task.device_id), task)
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
            lam=episode_lambda(task, self.header.lam),
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
            steps, good_size = _journal_steps(path)
            if path.stat().st_size != good_size:
                _truncate(path, good_size)
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
            target = self._set_aside(path.read_bytes(), path.stem)
            path.unlink()
            _fsync_dir(path.parent)
            return target

    def _append_episode(self, episode_id: str, steps: list[dict]) -> None:
        """Append the finished episode's line (caller holds the lock)."""
        if episode_id in self._finished_logs():
            raise PlayConflictError(
                f"episode {episode_id!r} was ended in another window; it is already in the run"
            )
        self._repair()
        line = orjson.dumps({"episode_id": episode_id, "steps": steps}) + b"\n"
        _append(self.episodes_path, line)


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
            image_source=run.image_source,
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
            _append(self.journal, line)
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
            _write_all(fd, data, self.journal)
        finally:
            os.close(fd)
        _fsync_dir(self.journal.parent)
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
            _fsync_dir(self.journal.parent)
        session = self.env.session
        assert session is not None
        self.result = session.finish().episode


# ------------------------------------------------------------------------ the page


class PlayState:
    """What the Play page does, over its session state (any mutable mapping: Streamlit's
    `st.session_state`, a dict in tests). The page draws; every decision is here.

    Keys: `play_episode` (the picked episode, the picker's key), `play_game` (the episode
    being played, an `EpisodePlay`), `play_seen` (the last click acted on),
    `play_message` (a message for the next drawing of the page, shown once), and the keys of
    the page's widgets: the image's last click (`click_key`), the action a click does, its
    parameters (per action) and the view a `Switch_view` click goes to.
    """

    EPISODE = "play_episode"
    GAME = "play_game"
    SEEN = "play_seen"
    MESSAGE = "play_message"
    ACTION = "play_action"
    CLICK_VIEW = "play_click_view"
    VIEW = "play_view"

    def __init__(self, run: HumanRun, state: MutableMapping[str, Any]) -> None:
        self.run = run
        self.state = state

    # ------------------------------------------------------------------ reading

    def episode_id(self) -> str:
        """The picked episode; at first (or when it is not a task), the next one to play."""
        picked = self.state.get(self.EPISODE)
        if picked not in self.run.bench.tasks:
            picked = self.run.next_episode() or next(iter(self.run.bench.tasks), None)
            if picked is None:
                raise PlayError(f"{self.run.bench.tasks_path} has no episode")
            self.state[self.EPISODE] = picked
        return picked

    def game(self) -> EpisodePlay | None:
        """The episode being played, started when the picked one is new; None when it was
        played already or has unfinished steps (the page offers to resume or discard)."""
        episode_id = self.episode_id()
        game = self.state.get(self.GAME)
        if game is not None and game.episode_id == episode_id:
            return game
        self.state[self.GAME] = None  # another episode was picked: its journal stays
        if self.run.status(episode_id).state != "new":
            return None
        try:
            game = self.run.start(episode_id)
        except replay.VGEError as exc:
            self.say("error", str(exc))
            return None
        self.state[self.GAME] = game
        return game

    def message(self) -> tuple[str, str] | None:
        """(tone, text) to show once, then forgotten."""
        return self.state.pop(self.MESSAGE, None)

    def say(self, tone: str, text: str) -> None:
        self.state[self.MESSAGE] = (tone, text)

    # ------------------------------------------------------------------ acting

    def click_key(self) -> str:
        """Key of the image component: one per episode, so a new episode starts unclicked."""
        return f"play_click:{self.episode_id()}"

    @staticmethod
    def params_key(type_: str) -> str:
        return f"play_params:{type_}"

    def chosen_action(self) -> str:
        chosen = self.state.get(self.ACTION)
        return chosen if chosen in CLICK_ACTIONS else CLICK_ACTIONS[0]

    def click(self) -> None:
        """Carry out the chosen action at the image's last click, once per click (the image
        reports its last click again on every rerun of the page)."""
        click = self.state.get(self.click_key())
        seen = click_id(click)
        if seen is None or seen == self.state.get(self.SEEN):
            return
        self.state[self.SEEN] = seen
        type_ = self.chosen_action()
        params = self.state.get(self.params_key(type_), PARAM_HINTS.get(type_, ("",))[0])
        try:
            chosen = click_action(type_, click_point(click), params, self.click_view())
        except PlayError as exc:
            self.say("error", str(exc))
            return
        self.act(chosen)

    def click_view(self) -> str:
        """The view a `Switch_view` click goes to: as chosen, else the dashboard (what a
        click is needed for), else the first view."""
        game = self.state.get(self.GAME)
        views = list(game.observation["views"]) if game is not None else []
        chosen = self.state.get(self.CLICK_VIEW)
        if chosen in views or not views:
            return chosen or ""
        return DASHBOARD if DASHBOARD in views else views[0]

    def switch_view(self, view: str) -> None:
        self.act(action("Switch_view", None, [view]))

    def wait(self) -> None:
        self.act(action("Timed_wait"))

    def act(self, chosen: Mapping[str, Any]) -> None:
        game = self.game()
        if game is None:
            return
        try:
            game.act(chosen)
        except replay.VGEError as exc:
            self.say("error", str(exc))
            if isinstance(exc, PlayConflictError) or game.broken:
                self.state[self.GAME] = None

    def give_up(self) -> None:
        """End the episode here (`log_ended`)."""
        game = self.game()
        if game is None:
            return
        try:
            if game.end() is None:
                self.say("info", "Nothing was played in this episode, so nothing was written.")
                self.state[self.GAME] = None
        except replay.VGEError as exc:
            self.say("error", str(exc))
            self.state[self.GAME] = None

    def resume(self) -> None:
        try:
            self.state[self.GAME] = self.run.resume(self.episode_id())
        except replay.VGEError as exc:
            self.say("error", str(exc))

    def discard(self) -> None:
        try:
            target = self.run.discard(self.episode_id())
        except replay.VGEError as exc:
            self.say("error", str(exc))
            return
        self.say("info", f"The unfinished steps were moved to {target}.")

    def pick_next(self) -> None:
        """Pick the next episode not played yet (after the picked one)."""
        following = self.run.next_episode(after=self.state.get(self.EPISODE))
        if following is None:
            self.say("info", "Every episode of the benchmark has been played in this run.")
            return
        self.state[self.EPISODE] = following


def click_hint(type_: str, view: str) -> str:
    """What a click on the image will do, in words."""
    if type_ == "Switch_view":
        return f"Click on it to switch to the {view} view with that point."
    return f"Click on it to {type_.lower()} there."


def goal_text(observation: Mapping[str, Any]) -> str:
    """`Goal 2 of 3: <instruction>` (the instruction of the current goal)."""
    index, total = int(observation["goal_index"]), int(observation["n_goals"])
    if index >= total:
        return f"All {total} goals completed."
    return f"Goal {index + 1} of {total}: {observation['instruction']}"


def budget_left(value: Any) -> str:
    """A budget as the page shows it (budgets are floats: λ may be fractional)."""
    return f"{float(value):g}"


def result_text(row: replay.EpisodeRow) -> str:
    """How an ended episode reads."""
    how = {
        "success": "Success",
        "budget_global": "Ended: the episode's step budget ran out",
        "budget_local": "Ended: the step budget of the current goal ran out",
        "log_ended": "Ended by the player",
    }.get(row.termination, row.termination)
    return (
        f"**{how}.** {row.goals_completed} of {_count(row.n_goals, 'goal')} completed in "
        f"{_count(row.L_act, 'step')} (the shortest way takes {row.L_opt}); SPL {row.spl:.2f}."
    )


def history(records: Sequence[StepRecord]) -> list[dict[str, Any]]:
    """The steps of the episode so far, newest first, for a table."""
    return [
        {"step": r.index, "action": r.action, "feedback": r.feedback} for r in reversed(records)
    ]


# ------------------------------------------------------------------------ file helpers


def _append(path: Path, data: bytes) -> None:
    """Append `data` to `path` with one write and make it durable."""
    fd = os.open(path, os.O_WRONLY | os.O_APPEND)
    try:
        _write_all(fd, data, path)
    finally:
        os.close(fd)


def _write_all(fd: int, data: bytes, path: Path) -> None:
    """One write of a whole record, then fsync: a crash leaves a prefix of it at worst."""
    written = os.write(fd, data)
    if written != len(data):  # a full disk; the torn line is cut off when next opened
        raise PlayError(f"{path}: only {written} of {len(data)} bytes could be written")
    os.fsync(fd)


def _write_new(path: Path, data: bytes) -> None:
    """Create `path` whole or not at all: written under a temporary name, then renamed."""
    tmp = path.with_name(f".{path.name}.tmp")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
    try:
        _write_all(fd, data, tmp)
    finally:
        os.close(fd)
    os.replace(tmp, path)
    _fsync_dir(path.parent)


def _truncate(path: Path, size: int) -> None:
    with open(path, "r+b") as fh:
        fh.truncate(size)
        fh.flush()
        os.fsync(fh.fileno())


def _fsync_dir(path: Path) -> None:
    """Make a file's creation, rename or removal in `path` durable."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _journal_header(path: Path) -> str | None:
    """The episode id a journal's first line names (None if it cannot be read)."""
    try:
        with open(path, "rb") as fh:
            first = fh.readline()
        head = orjson.loads(first)
    except (OSError, orjson.JSONDecodeError):
        return None
    episode_id = head.get("episode_id") if isinstance(head, dict) else None
    return episode_id if isinstance(episode_id, str) else None


def _journal_steps(path: Path) -> tuple[list[dict], int]:
    """The steps of a journal and the byte size they end at. A last line without its
    newline is a write the app died in (its feedback was never shown) and is left out; a
    complete line that is not a step cannot come from a crash and is an error."""
    data = path.read_bytes()
    steps: list[dict] = []
    pos = data.find(b"\n") + 1  # after the header line
    while pos > 0:
        end = data.find(b"\n", pos)
        if end < 0:
            break
        try:
            step = orjson.loads(data[pos:end])
        except orjson.JSONDecodeError:
            step = None
        if not isinstance(step, dict) or not isinstance(step.get("action"), dict):
            raise PlayError(f"{path}: line {len(steps) + 2} is not a step; discard the episode")
        steps.append(step)
        pos = end + 1
    return steps, pos


__all__ = [
    "CLICK_ACTIONS",
    "DEFAULT_MODEL",
    "DEFAULT_RUN_DIR",
    "FEEDBACK_TONES",
    "IMAGE_SIZE",
    "INTERACTIONS",
    "PARAM_HINTS",
    "SCALE",
    "EpisodePlay",
    "EpisodeStatus",
    "HumanRun",
    "PlayState",
    "StepRecord",
    "action",
    "action_text",
    "budget_left",
    "click_action",
    "click_hint",
    "click_id",
    "click_point",
    "goal_text",
    "history",
    "parse_params",
    "result_text",
    "scale_coordinate",
]
