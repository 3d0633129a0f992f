"""A worker process of `vge replay`: what it keeps between batches.

`WorkerState`: the caches of a process, all bounded (the benchmark opened once, episode
setups, the episodes that passed their checks, SSM bytes and view images for the MCAP
files); `worker_state(bench)` is this process's, whichever executor runs the batches here.
How long a worker lives is `_lifetime`'s.
"""

from __future__ import annotations

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
