"""Where batches run: in this process, in worker processes, or on a Ray cluster (`_ray`).

An executor runs a batch function (`_worker.replay_batch`, or the sweep's) on picklable
tasks; `in_order` hands the results back in the order of the tasks with a bounded number in
flight, so memory does not grow with the size of the logs. The files written do not depend
on the executor: every executor calls the same function on the same tasks.
"""

from __future__ import annotations

import multiprocessing
from collections import Counter, deque
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any, Generic, Protocol, TypeVar

from .._errors import ConfigError, WorkerError

T = TypeVar("T")
Batch = Callable[[Any], Any]


class Executor(Protocol):
    """Runs a batch function on tasks; `result(handle)` waits for one."""

    slots: int  # batches it can work on at once
    nodes: Counter[str]  # batches finished per node (filled by cluster executors)

    def submit(self, fn: Batch, task: Any) -> object: ...

    def result(self, handle: object) -> Any: ...

    def close(self) -> None: ...


class InProcess:
    """Batches run here, one after the other (`workers=1`)."""

    slots = 1

    def __init__(self) -> None:
        self.nodes: Counter[str] = Counter()

    def submit(self, fn: Batch, task: Any) -> Any:
        return fn(task)

    def result(self, handle: object) -> Any:
        return handle

    def close(self) -> None:
        pass


class WorkerProcesses:
    """N worker processes (spawned). Batch k of every run goes to worker k mod N: runs that
    list the same episodes in the same order then find each task's plan in that worker's
    cache."""

    def __init__(self, workers: int) -> None:
        context = multiprocessing.get_context("spawn")
        self.slots = workers
        self.nodes: Counter[str] = Counter()
        self.pools = [ProcessPoolExecutor(max_workers=1, mp_context=context) for _ in range(workers)]

    def submit(self, fn: Batch, task: Any) -> Future[Any]:
        index = getattr(task, "index", 0)
        return self.pools[index % len(self.pools)].submit(fn, task)

    def result(self, handle: object) -> Any:
        try:
            return handle.result()  # type: ignore[attr-defined]
        except BrokenProcessPool:
            raise WorkerError(
                "a replay worker process died (killed or out of memory; a script calling "
                "replay_runs with workers > 1 needs an `if __name__ == '__main__':` guard)"
            ) from None

    def close(self) -> None:
        for pool in self.pools:
            pool.shutdown(wait=True, cancel_futures=True)


def make_executor(workers: int = 1, ray: str | None = None) -> Executor:
    """This process (`workers=1`), `workers` processes, or the Ray cluster at `ray`
    (`auto`: the cluster this host belongs to or `RAY_ADDRESS`; `local`: a cluster started
    in this process; else an address)."""
    if ray is not None:
        from ._ray import RayCluster

        return RayCluster(ray)
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ConfigError(f"workers must be a positive integer, not {workers!r}")
    return InProcess() if workers == 1 else WorkerProcesses(workers)


class _Pending(Generic[T]):
    __slots__ = ("item", "task", "handle")

    def __init__(self, item: T, task: Any, handle: object) -> None:
        self.item = item
        self.task = task
        self.handle = handle


def in_order(
    executor: Executor,
    fn: Batch,
    items: Iterator[tuple[T, Any]],
    ahead: int,
) -> Iterator[tuple[T, Any, Any]]:
    """(item, task, fn(task)) in the order of `items`, at most `ahead` tasks in flight; an
    item whose task is None (a marker) comes back with result None at its place."""
    pending: deque[_Pending[T]] = deque()
    in_flight = 0
    try:
        for item, task in items:
            pending.append(_Pending(item, task, None if task is None else executor.submit(fn, task)))
            in_flight += task is not None
            while pending and (in_flight >= ahead or pending[0].task is None):
                head = pending.popleft()
                if head.task is None:
                    yield head.item, None, None
                else:
                    in_flight -= 1
                    yield head.item, head.task, executor.result(head.handle)
        while pending:
            head = pending.popleft()
            result = None if head.task is None else executor.result(head.handle)
            yield head.item, head.task, result
    finally:
        for rest in pending:
            cancel = getattr(rest.handle, "cancel", None)
            if cancel is not None:
                cancel()
