"""Where `WorkerProcesses` runs a batch: this process keeps batch k when k mod N is N - 1
(the first batch of a run, and every run of one batch, goes to a worker), the rest go to
the pool, and the results come back whole wherever they ran."""

from __future__ import annotations

import multiprocessing
from types import SimpleNamespace

import pytest

from replay.io._executor import WorkerProcesses


@pytest.mark.parametrize(("workers", "kept"), [(2, [1, 3, 5]), (3, [2, 5])])
def test_this_process_keeps_batch_k_when_k_mod_n_is_n_minus_1(
    workers: int, kept: list[int]
) -> None:
    executor = WorkerProcesses(workers)
    try:
        tasks = [SimpleNamespace(index=k) for k in range(6)]
        shares = [executor.submit(repr, task) for task in tasks]
        assert [k for k, share in enumerate(shares) if share.future is None] == kept
        assert [executor.result(share) for share in shares] == [repr(t) for t in tasks]
    finally:
        executor.close()


def _ready_here() -> tuple[bool, list[str]]:
    """In a worker: whether the batch function is imported, and the benchmarks it opened."""
    import sys

    from replay.io import _worker

    return "replay.io._batch" in sys.modules, sorted(_worker._states)


@pytest.mark.parametrize("bench_given", [False, True])
def test_given_bench_the_workers_start_at_once_ready_for_a_batch(
    sample, bench_given: bool
) -> None:
    """Without BENCH a pool starts a worker when a task needs one; with it, `vge replay`'s
    workers start as the executor is made, import the batch function and open BENCH."""
    bench = str(sample.bench)
    before = len(multiprocessing.active_children())
    executor = WorkerProcesses(3, bench if bench_given else None)
    try:
        assert len(multiprocessing.active_children()) - before == (2 if bench_given else 0)
        ready = executor.pool.submit(_ready_here).result()
        assert ready == ((True, [bench]) if bench_given else (False, []))
    finally:
        executor.close()
