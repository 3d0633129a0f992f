"""A worker process of `vge replay`: what it keeps between batches, and how long it lives.

- `WorkerState`: the caches of a process, all bounded (the benchmark opened once, episode
  setups, the episodes that passed their checks, SSM bytes and view images for the MCAP
  files); `worker_state(bench)` is this process's, whichever executor runs the batches here.
- `end_with_parent` (a pool's initializer) ties a worker to the process that started it.
  Killed with `kill -9`, a parent leaves its pool's workers waiting for tasks that will never
  come, and with them the multiprocessing resource tracker, which lives until the last
  process holding its pipe has gone: on Linux the kernel kills the worker when the parent
  thread that started it ends (`PR_SET_PDEATHSIG`); elsewhere a thread of the worker
  notices, within `WATCH_SECONDS`, that it has another parent. Ray's workers end with their
  job as Ray ends them.
"""

from __future__ import annotations

import ctypes
import os
import signal
import sys
import threading
import time
from dataclasses import dataclass, field
from typing import NamedTuple

from .._errors import TaskError
from ..semantics import EpisodeSetup, Machine, Task, setup_episode
from ._images import ImageSource, ViewImage, as_view_image
from ._load import Benchmark

SETUP_CACHE_SIZE = 50_000
"""Episode setups (plans), and episodes ready to replay, kept per process; bounds memory
whatever the number of tasks."""
_IMAGE_CACHE_SIZE = 128
_SSM_CACHE_SIZE = 256
_BENCHES = 4


def _remember(cache: dict, key: object, value: object, limit: int) -> None:
    """Insert into a bounded cache, dropping the oldest entry when full."""
    if len(cache) >= limit:
        del cache[next(iter(cache))]
    cache[key] = value


class Ready(NamedTuple):
    """An episode that passed every check of its lines (its task, its device's SSM, its
    setup): what a line of it needs besides the line."""

    machine: Machine
    task: Task
    setup: EpisodeSetup


@dataclass
class WorkerState:
    """Per-process caches (bounded): the benchmark, episode setups, the episodes ready to
    replay (by id; an episode that failed a check is not kept, so each of its lines is
    checked and reported again), SSM bytes, view images."""

    bench: Benchmark
    setups: dict[str, EpisodeSetup | TaskError] = field(default_factory=dict)
    ready: dict[str, Ready] = field(default_factory=dict)
    ssm_bytes: dict[str, bytes] = field(default_factory=dict)
    images: dict[tuple[str, str], ViewImage | None] = field(default_factory=dict)

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

    def remember_ready(self, ready: Ready) -> None:
        _remember(self.ready, ready.task.episode_id, ready, SETUP_CACHE_SIZE)

    def image(self, source: ImageSource, machine: Machine, view: str) -> ViewImage | None:
        key = (machine.device_id, view)
        if key not in self.images:
            _remember(self.images, key, as_view_image(source(machine, view)), _IMAGE_CACHE_SIZE)
        return self.images[key]

    def ssm(self, machine: Machine) -> bytes:
        got = self.ssm_bytes.get(machine.device_id)
        if got is None:
            from ._mcap import attached_ssm  # the MCAP libraries load only with --mcap

            got = attached_ssm(machine)
            _remember(self.ssm_bytes, machine.device_id, got, _SSM_CACHE_SIZE)
        return got


_states: dict[str, WorkerState] = {}


def worker_state(bench: str) -> WorkerState:
    """This process's state for a benchmark directory (opened once)."""
    got = _states.get(bench)
    if got is None:
        got = WorkerState(Benchmark.open(bench))
        _remember(_states, bench, got, _BENCHES)
    return got


def adopt(state: WorkerState, bench: str) -> None:
    """Use an already opened benchmark for `bench` in this process (the runner's own)."""
    _remember(_states, bench, state, _BENCHES)


PR_SET_PDEATHSIG = 1
"""prctl(2) option: the signal a process receives when its parent ends (linux/prctl.h)."""
WATCH_SECONDS = 1.0
"""How often the watch thread, where there is no PR_SET_PDEATHSIG, checks the parent."""


def end_with_parent(parent: int, *, death_signal: bool = sys.platform == "linux") -> None:
    """Make this process end when process `parent` does (the initializer of a pool's
    workers, given the pool owner's pid); `death_signal=False` uses the watch thread."""
    if not (death_signal and _arm_death_signal()):
        threading.Thread(target=_watch, args=(parent,), name="vge-parent", daemon=True).start()
    if os.getppid() != parent:  # the parent was gone before anything was armed
        os._exit(1)


def _arm_death_signal() -> bool:
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0) == 0
    except (OSError, AttributeError):  # no C library, or no prctl in it
        return False


def _watch(parent: int) -> None:
    while os.getppid() == parent:
        time.sleep(WATCH_SECONDS)
    os._exit(1)
