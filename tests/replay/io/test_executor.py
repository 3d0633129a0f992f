"""Where `WorkerProcesses` runs a batch: this process keeps batch k when k mod N is N - 1
(the first batch of a run, and every run of one batch, goes to a worker), the rest go to
the pool, and the results come back whole wherever they ran."""

from __future__ import annotations

import json
import multiprocessing
import subprocess
import sys
import tempfile
from pathlib import Path
from types import SimpleNamespace

import pytest

from replay.io._executor import WorkerProcesses

ROOT = Path(__file__).parents[3]


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


def _opened_here() -> list[str]:
    """In a worker: the benchmarks it has opened."""
    from replay.io import _worker

    return sorted(_worker._states)


@pytest.mark.parametrize("bench_given", [False, True])
def test_given_bench_the_workers_start_at_once_and_open_it(sample, bench_given: bool) -> None:
    """Without BENCH a pool starts a worker when a task needs one; with it, `vge replay`'s
    workers start as the executor is made, and open BENCH before any task."""
    bench = str(sample.bench)
    before = len(multiprocessing.active_children())
    executor = WorkerProcesses(3, bench if bench_given else None)
    try:
        assert len(multiprocessing.active_children()) - before == (2 if bench_given else 0)
        opened = executor.pool.submit(_opened_here).result()
        assert opened == ([bench] if bench_given else [])
    finally:
        executor.close()


def test_tasks_reach_the_workers_through_files_deleted_once_read(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A task for a worker goes through a file of the executor's private directory (the
    pipe carries its name); each file is gone once its task ran, wherever it ran (a worker
    deletes what it read; this process what it took back), and the directory at the close."""
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    executor = WorkerProcesses(2)
    try:
        (spool,) = tmp_path.iterdir()
        tasks = [SimpleNamespace(index=k) for k in range(6)]
        shares = [executor.submit(repr, task) for task in tasks]
        assert sum(share.spooled is not None for share in shares) == 3  # batches 0, 2, 4
        assert [executor.result(share) for share in shares] == [repr(t) for t in tasks]
        assert list(spool.iterdir()) == []
    finally:
        executor.close()
    assert list(tmp_path.iterdir()) == []


FORK_PROBE = """
import json, multiprocessing, sys, threading
from replay.io import _worker
from replay.io._executor import WorkerProcesses

def state_id(bench):
    return id(_worker._states[bench])

bench = sys.argv[1]
state = _worker.worker_state(bench)
seen = {}
executor = WorkerProcesses(2, bench, fork=True)
try:
    seen["asked"] = executor.start_method
    seen["inherited"] = executor.pool.submit(state_id, bench).result() == id(state)
finally:
    executor.close()
executor = WorkerProcesses(2, fork=True)  # no BENCH: forked at once all the same
seen["without_bench"] = [executor.start_method, len(multiprocessing.active_children())]
executor.close()
executor = WorkerProcesses(2, fork=False)
seen["not_asked"] = executor.start_method
executor.close()
release = threading.Event()
other = threading.Thread(target=release.wait)
other.start()
executor = WorkerProcesses(2, fork=True)
seen["another_thread"] = executor.start_method
executor.close()
release.set()
other.join()
print(json.dumps(seen))
"""


@pytest.mark.skipif(sys.platform != "linux", reason="workers are forked on Linux only")
def test_workers_are_forked_when_asked_and_no_other_thread_runs(sample) -> None:
    """In a fresh interpreter (one thread): asked to fork, the pool forks at once (BENCH
    given or not: later this process may run threads), and its worker has this process's
    opened BENCH (the very object); not asked, or with another thread running, it spawns.
    (A test process of pytest-xdist runs threads of its own, so this is checked in a
    subprocess.)"""
    done = subprocess.run(
        [sys.executable, "-c", FORK_PROBE, str(sample.bench)],
        capture_output=True, text=True, timeout=300, cwd=ROOT,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout.splitlines()[-1]) == {
        "asked": "fork",
        "inherited": True,
        "without_bench": ["fork", 1],
        "not_asked": "spawn",
        "another_thread": "spawn",
    }
