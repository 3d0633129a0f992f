"""`vge/Device-v0`: one benchmark episode at a time, as a Gymnasium environment.

A thin wrapper over `EpisodeSession`, the object `replay_episode` loops over: each `step`
is one `advance` of the session with the action as a log step would carry it, so a live
episode and the replay of its log give the same rows (zero divergent steps by
construction). Nothing inside a step reads a clock or draws a random number; the only random
choice is which episode `reset` picks when it is not told, from the seeded `np_random`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from functools import cached_property
from pathlib import Path
from typing import Any

import gymnasium
import msgspec
import numpy as np
from gymnasium.error import ResetNeeded

from .._errors import ActionError, ConfigError, VGEError
from ..io import BenchImages, Benchmark, ImageSource
from ..semantics import (
    BUDGET_GLOBAL,
    BUDGET_LOCAL,
    DASHBOARD,
    SUCCESS,
    ActionRecord,
    Continuation,
    EpisodeSession,
    LogStep,
    Machine,
    StepRow,
    episode_lambda,
)
from ._bounds import BenchBounds, bench_bounds
from ._images import ViewImages
from ._spaces import action_space, observation_space

STEP_FIELDS: tuple[str, ...] = tuple(StepRow.__struct_fields__)
"""The keys a step's `info` may hold: the columns of the steps table (PROTOCOL §7.2)."""

TERMINATED = SUCCESS
TRUNCATED = (BUDGET_GLOBAL, BUDGET_LOCAL)

_RESET_OPTIONS = ("episode_id", "continuation")


def step_info(row: Sequence[Any]) -> dict[str, Any]:
    """A step's `info`: its row of the steps table without the null columns. Gymnasium's vector
    envs batch each key into an array typed by the first value they see, so a null after a
    number fails (or turns False); an absent key is marked in `infos["_<key>"]` instead."""
    return {key: value for key, value in zip(STEP_FIELDS, row, strict=True) if value is not None}


def log_step_of(action: str | Mapping[str, Any] | LogStep) -> LogStep:
    """An action as the log carries it (PROTOCOL §1.4): text is the model's `output`; a
    mapping is a structured `action` `{"type", "coord", "params"}`; a log step is taken as
    it is (a step of another run's log, replayed by a continuation)."""
    if isinstance(action, LogStep):
        return action
    if isinstance(action, str):
        return LogStep(output=action)
    if isinstance(action, Mapping):
        try:
            return LogStep(action=msgspec.convert(dict(action), ActionRecord))
        except msgspec.ValidationError as exc:
            raise ActionError(f"structured action {dict(action)!r}: {exc}") from None
    raise ActionError(
        f"an action is the model's text or a mapping {{type, coord, params}}, not {type(action).__name__}"
    )


class DeviceEnv(gymnasium.Env):
    """A device of a VGEBench-style benchmark, operated by clicking points of its views.

    `bench` is a benchmark directory (PROTOCOL §1.1) or an open `Benchmark`. `lam` is the
    run's λ (a task's own λ wins, PROTOCOL §3.5). `episodes` limits the episodes `reset` picks
    from when it is not given one. `image_source(machine, view)` supplies view images (default:
    the benchmark's own, `replay.BenchImages`; a caller may pass a source that also renders
    views the benchmark has no picture of); every view is shown at
    `image_width` x `image_height`. `run_id`, `model` and `agent_kind` fill the matching
    fields of `info`. docs/LIVE.md describes the observation.

    The observation space is bounded by the benchmark (`bounds`), which plans every task: it
    is built when first read, so the live tools, which never read it, do not pay for it.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 1}

    def __init__(
        self,
        bench: str | Path | Benchmark,
        *,
        lam: float | None = None,
        episodes: Sequence[str] | None = None,
        image_width: int = 768,
        image_height: int = 768,
        image_source: ImageSource | None = None,
        render_mode: str | None = None,
        run_id: str = "live",
        model: str = "live",
        agent_kind: str = "vlm",
    ) -> None:
        self.bench = bench if isinstance(bench, Benchmark) else Benchmark.open(bench)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ConfigError(f"render_mode must be 'rgb_array' or None, not {render_mode!r}")
        if image_width < 1 or image_height < 1:
            raise ConfigError(f"image size must be positive, not {image_width} x {image_height}")
        self.render_mode = render_mode
        self.lam = None if lam is None else float(lam)
        if episodes is None:
            pool = list(self.bench.tasks)
        else:
            pool = list(episodes)
            unknown = [e for e in pool if e not in self.bench.tasks]
            if unknown:
                raise ConfigError(
                    f"episode(s) not in {self.bench.tasks_path}: {', '.join(map(repr, unknown))}"
                )
        if not pool:
            raise ConfigError(f"{self.bench.tasks_path}: no episode to play")
        self.episode_pool: tuple[str, ...] = tuple(pool)
        self.image_size = (image_width, image_height)
        self.action_space = action_space()
        source = BenchImages(str(self.bench.root)) if image_source is None else image_source
        self._images = ViewImages(source, image_width, image_height)
        self._head = (run_id, model, agent_kind)
        self.session: EpisodeSession | None = None
        """The episode being played (the same object `replay_episode` drives)."""
        self.machine: Machine | None = None
        self._feedback = ("", "")

    @cached_property
    def bounds(self) -> BenchBounds:
        """The benchmark's maxima under this environment's λ (they bound the spaces)."""
        return bench_bounds(self.bench, self.lam)

    @cached_property
    def observation_space(self) -> gymnasium.spaces.Dict:  # type: ignore[override]
        return observation_space(*self.image_size, self.bounds)

    # ------------------------------------------------------------------ Gymnasium API

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, Any], dict[str, Any]]:
        """Start an episode: `options={"episode_id": ...}`, else a seeded choice among the
        playable episodes of the pool. `options["continuation"]` (a `replay.Continuation`,
        with an episode id) makes it an episode of a continuation run: its steps get their
        origin from it (PROTOCOL §7.2, §10.4)."""
        super().reset(seed=seed)
        options = dict(options or {})
        unknown = sorted(set(options) - set(_RESET_OPTIONS))
        if unknown:
            raise ConfigError(
                f"unknown reset option(s) {', '.join(unknown)}; known: {', '.join(_RESET_OPTIONS)}"
            )
        episode_id = options.get("episode_id")
        continuation = options.get("continuation")
        if continuation is not None and not isinstance(continuation, Continuation):
            raise ConfigError("reset option continuation must be a replay.Continuation")
        if continuation is not None and episode_id is None:
            raise ConfigError("reset option continuation needs the episode_id it continues")
        if episode_id is not None:
            self._start(str(episode_id), continuation)
        else:
            self._start_any()
        self._feedback = ("", "")
        return self._observation(), self._reset_info()

    def step(
        self, action: str | Mapping[str, Any] | LogStep
    ) -> tuple[dict[str, Any], float, bool, bool, dict[str, Any]]:
        """One agent response: the model's text, or a structured action (or a `LogStep`
        holding either)."""
        session = self.session
        if session is None:
            raise ResetNeeded("call reset() before step()")
        if session.done:
            raise ResetNeeded(f"the episode ended ({session.termination}); call reset()")
        row = session.advance(log_step_of(action))
        info = step_info(row)
        self._feedback = (info["feedback_text"], info["feedback_kind"])
        termination = session.termination
        return (
            self._observation(),
            float(info["completed_goals"]),
            termination == TERMINATED,
            termination in TRUNCATED,
            info,
        )

    def render(self) -> np.ndarray | None:
        """The current view (`rgb_array`), or None without a render mode."""
        if self.render_mode is None or self.session is None:
            return None
        return self._image()

    # ------------------------------------------------------------------ internals

    def _start(self, episode_id: str, continuation: Continuation | None = None) -> None:
        entry = self.bench.tasks.get(episode_id)
        if entry is None:
            raise ConfigError(f"episode {episode_id!r} is not in {self.bench.tasks_path}")
        task = entry.task
        machine = self.bench.machine(task.device_id)
        self.session = EpisodeSession(
            machine,
            task,
            lam=episode_lambda(task, self.lam),
            run_id=self._head[0],
            model=self._head[1],
            agent_kind=self._head[2],
            continuation=continuation,
        )
        self.machine = machine

    def _start_any(self) -> None:
        """Try the pool in a seeded order; tasks that cannot be played are passed over."""
        order = self.np_random.permutation(len(self.episode_pool))
        problems: list[str] = []
        for index in order:
            try:
                self._start(self.episode_pool[int(index)])
                return
            except VGEError as exc:
                problems.append(str(exc))
        raise ConfigError(f"no playable episode in the pool (first problem: {problems[0]})")

    def _image(self) -> np.ndarray:
        assert self.session is not None and self.machine is not None
        return self._images.array(self.machine, self.session.sim.view)

    def _dashboard_unlocked(self) -> int:
        assert self.session is not None and self.machine is not None
        return int(self.session.sim.unlocked and DASHBOARD in self.machine.views)

    def _observation(self) -> dict[str, Any]:
        session = self.session
        assert session is not None and self.machine is not None
        sim = session.sim
        text, kind = self._feedback
        return {
            "episode_id": session.task.episode_id,
            "step": len(session.rows),
            "image": self._image(),
            "view": sim.view,
            "views": tuple(self.machine.views),
            "dashboard_unlocked": self._dashboard_unlocked(),
            "instruction": session.instruction,
            "goal_index": session.current,
            "n_goals": session.n_goals,
            "feedback": text,
            "feedback_kind": kind,
            "budget_global_left": np.array(session.budget.global_left, dtype=np.float64),
            "budget_local_left": np.array(session.budget.local, dtype=np.float64),
        }

    def _reset_info(self) -> dict[str, Any]:
        session = self.session
        assert session is not None and self.machine is not None
        names = self.machine.states
        return {
            "device_id": self.machine.device_id,
            "category": self.machine.category,
            "lambda": session.budget.lam,
            "budget_global": session.budget.budget_global,
            "goals": [names[g] for g in session.goals],
            "c_opt": list(session.c_opt),
            "initial_state": names[session.setup.initial_state],
        }


__all__ = ["STEP_FIELDS", "DeviceEnv", "log_step_of", "step_info"]
