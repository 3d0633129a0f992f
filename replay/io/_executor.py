"""Where batches run: in this process, in worker processes, or on a Ray cluster (`_ray`).

An executor runs a batch function (`_batch.replay_batch`, or the sweep's) on picklable
tasks; `in_order` hands the results back in the order of the tasks with a bounded number in
flight, so memory does not grow with the size of the logs. The files written do not depend
on the executor: every executor calls the same function on the same tasks.
"""

from __future__ import annotations

import multiprocessing
import os
import pickle
import shutil
import sys
import tempfile
import threading
from collections import Counter, deque
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any, Generic, Protocol, TypeVar

from .._errors import ConfigError, WorkerError
from ._lifetime import start_worker

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


class _Share:
    """A task given to `WorkerProcesses`: kept here (`future` None) or sent to the pool
    through a file (`spooled`, which the worker deletes once read)."""

    __slots__ = ("fn", "task", "future", "spooled", "done", "value")

    def __init__(
        self, fn: Batch, task: Any, future: Future[Any] | None, spooled: str | None = None
    ) -> None:
        self.fn = fn
        self.task = task
        self.future = future
        self.spooled = spooled
        self.done = False
        self.value: Any = None

    def run_here(self) -> None:
        if self.spooled is not None:  # taken back before a worker read it
            os.unlink(self.spooled)
        self.value = self.fn(self.task)
        self.done = True
        self.fn = self.task = None  # the task's lines are no longer needed


def _spool(directory: str, task: Any) -> str:
    """The task pickled into a new file of `directory`; its path."""
    fd, path = tempfile.mkstemp(dir=directory)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(pickle.dumps(task, protocol=pickle.HIGHEST_PROTOCOL))
    except BaseException:  # a full disk: no part of it left behind
        os.unlink(path)
        raise
    return path


def _run_spooled(fn: Batch, path: str) -> Any:
    """In a worker: the task of a spooled file (deleted once read), run."""
    with open(path, "rb") as fh:
        data = fh.read()
    os.unlink(path)
    return fn(pickle.loads(data))


def start_method(fork: bool) -> str:
    """How `WorkerProcesses` starts its workers: "fork" when asked for, on Linux, while this
    process runs no thread but the main one; else "spawn"."""
    if fork and sys.platform == "linux" and threading.active_count() == 1:
        return "fork"
    return "spawn"


class WorkerProcesses:
    """N workers: this process and N - 1 worker processes. The task of batch k stays here when
    k mod N is N - 1 and goes to the pool otherwise (runs that list the same episodes in the
    same order then find each task's plan in the same process's cache). So the first batch
    of every run goes to a worker, and with it every run of one batch, and this process,
    which also reads the lines, takes the reports and commits the runs, keeps the smaller
    share (a run's last batch is mostly short): with 2 workers on the full synthetic
    benchmark its CPU came out 1.06 to 1.17 times the worker's (it had 1.5 to 1.6 times
    the worker's when it kept batch 0, and the wall time followed it). While waiting for a
    result, this process works: on its own tasks first, then on pool tasks that no worker
    has started (a pending future can be cancelled). So no process idles while another has
    a queue.

    A task sent to a worker goes through a file of a private temporary directory, which the
    worker deletes once read; the pool's pipe carries its name. Through the pipe, a batch's
    15 MB of lines moved only when this process's threads held the GIL, which the kernel
    keeps while it replays, and the worker waited for them between batches: on the full
    synthetic benchmark with 2 workers, 3.94 and 3.98 s of wall time against 4.03 and 4.05
    (two sets of 8 alternations, the same CPU).

    How the workers start (`start_method`): forked where `fork` asks for it, on Linux, while
    this process runs no other thread; spawned otherwise. A forked worker begins with what
    this process has imported and opened, BENCH included (`_worker.adopt`): `replay_runs`
    makes its pool once it has opened BENCH and before it starts a thread of its own, and a
    worker is ready at once, where a spawned one spends 0.3 s of CPU importing the engine and
    opening BENCH again (docs/PERFORMANCE.md, "Replay", eighth part). A fork copies the
    locks of this process's other threads as they are, held ones included, so with another
    thread running the workers are spawned; the native threads of the libraries the engine
    loads (jemalloc's, Arrow's, OpenBLAS's) are prepared for a fork by the libraries
    themselves. macOS's system libraries are not fork-safe at all.

    Forked workers start at once, while this process still runs no other thread. Given
    BENCH, spawned ones start at once too and open it (`_lifetime.start_worker`); otherwise
    a spawned pool starts a worker when a task needs one."""

    def __init__(self, workers: int, bench: str | None = None, *, fork: bool = False) -> None:
        self.start_method = start_method(fork)
        context = multiprocessing.get_context(self.start_method)
        self.slots = workers
        self.nodes: Counter[str] = Counter()
        self.pool = ProcessPoolExecutor(
            max_workers=workers - 1,
            mp_context=context,
            initializer=start_worker,  # no worker outlives this process (`_lifetime`)
            initargs=(os.getpid(), bench),
        )
        self._open: deque[_Share] = deque()  # submitted, result not taken yet
        self._spool = tempfile.mkdtemp(prefix="vge-tasks-")  # private (0700), removed at close
        if bench is not None or self.start_method == "fork":  # a fork: now, before any thread
            for _ in range(workers - 1):  # a pool starts a worker per task it is given
                self.pool.submit(os.getpid)

    def submit(self, fn: Batch, task: Any) -> _Share:
        index = getattr(task, "index", 0)
        here = index % self.slots == self.slots - 1
        if here:
            share = _Share(fn, task, None)
        else:
            try:
                path = _spool(self._spool, task)
            except OSError:  # no room for it there: through the pipe, as a pool sends it
                share = _Share(fn, task, self.pool.submit(fn, task))
            else:
                share = _Share(fn, task, self.pool.submit(_run_spooled, fn, path), path)
        self._open.append(share)
        return share

    def result(self, handle: object) -> Any:
        share: _Share = handle  # type: ignore[assignment]
        while not share.done:
            if share.future is None or share.future.cancel():
                share.run_here()
            elif share.future.done() or not self._work_on_another(share):
                share.value = self._pool_result(share.future)
                share.done = True
        self._open.remove(share)
        return share.value

    def _work_on_another(self, waiting: _Share) -> bool:
        """Run one other open task here: one of ours, else one no worker has started."""
        for share in self._open:
            if share is not waiting and not share.done and share.future is None:
                share.run_here()
                return True
        for share in self._open:
            if share is not waiting and not share.done and share.future.cancel():  # type: ignore[union-attr]
                share.run_here()
                return True
        return False

    @staticmethod
    def _pool_result(future: Future[Any]) -> Any:
        try:
            return future.result()
        except BrokenProcessPool:
            raise WorkerError(
                "a replay worker process died (killed or out of memory; a script calling "
                "replay_runs with workers > 1 needs an `if __name__ == '__main__':` guard)"
            ) from None

    def close(self) -> None:
        self._open.clear()
        self.pool.shutdown(wait=True, cancel_futures=True)
        shutil.rmtree(self._spool, ignore_errors=True)  # what no worker read (one that died)


def make_executor(
    workers: int = 1, ray: str | None = None, bench: str | None = None, *, fork: bool = False
) -> Executor:
    """This process (`workers=1`), `workers` processes, or the Ray cluster at `ray`
    (`auto`: the cluster this host belongs to or `RAY_ADDRESS`; `local`: a cluster started
    in this process; else an address). Worker processes end with this process; on Linux
    also with the thread that first submits to them, which must outlive the executor. Given
    `bench` (as the tasks will name it), worker processes start now and open it unless they
    have it. `fork`: fork the workers where that is safe (`WorkerProcesses`), for a caller
    whose workers use nothing it has loaded but the engine (not polars, not DuckDB, whose
    thread pools a fork leaves behind)."""
    if ray is not None:
        from ._ray import RayCluster

        return RayCluster(ray)
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ConfigError(f"workers must be a positive integer, not {workers!r}")
    return InProcess() if workers == 1 else WorkerProcesses(workers, bench, fork=fork)


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
