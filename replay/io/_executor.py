"""Where batches run: in this process, or in worker processes; results come back in order.

Every executor calls the same function (`_worker.replay_batch`) on the same tasks, so the
files do not depend on the executor. The runner keeps at most `ahead` batches in flight,
so memory does not grow with the size of the logs.
"""

from __future__ import annotations

import multiprocessing
from collections import deque
from collections.abc import Iterator
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Generic, Protocol, TypeVar

from .._errors import WorkerError
from ._task import BatchFailure, BatchReport, BatchTask
from ._worker import replay_batch

Result = BatchReport | BatchFailure
T = TypeVar("T")


class Executor(Protocol):
    """Runs `replay_batch` on tasks; `result(handle)` waits for one."""

    slots: int  # batches it can work on at once

    def submit(self, task: BatchTask) -> object: ...

    def result(self, handle: object) -> Result: ...

    def close(self) -> None: ...


class InProcess:
    """Batches replayed here, one after the other (`workers=1`)."""

    slots = 1

    def submit(self, task: BatchTask) -> Result:
        return replay_batch(task)

    def result(self, handle: object) -> Result:
        return handle  # type: ignore[return-value]

    def close(self) -> None:
        pass


class WorkerProcesses:
    """N worker processes (spawned). Batch k of every run goes to worker k mod N: runs that
    list the same episodes in the same order then find each task's plan in that worker's
    cache."""

    def __init__(self, workers: int) -> None:
        context = multiprocessing.get_context("spawn")
        self.slots = workers
        self.pools = [ProcessPoolExecutor(max_workers=1, mp_context=context) for _ in range(workers)]

    def submit(self, task: BatchTask) -> Future[Result]:
        return self.pools[task.index % len(self.pools)].submit(replay_batch, task)

    def result(self, handle: object) -> Result:
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


class Pending(Generic[T]):
    """An item of the ordered stream: a submitted task, or a marker passed through in order."""

    __slots__ = ("item", "task", "handle")

    def __init__(self, item: T, task: BatchTask | None, handle: object) -> None:
        self.item = item
        self.task = task
        self.handle = handle


def in_order(
    executor: Executor,
    items: Iterator[tuple[T, BatchTask | None]],
    ahead: int,
) -> Iterator[tuple[T, BatchTask | None, Result | None]]:
    """(item, task, result) in the order of `items`, with at most `ahead` tasks in flight;
    an item without a task (a marker) comes back with result None at its place."""
    pending: deque[Pending[T]] = deque()
    in_flight = 0
    try:
        for item, task in items:
            pending.append(Pending(item, task, None if task is None else executor.submit(task)))
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
