"""Where `WorkerProcesses` runs a batch: this process keeps batch k when k mod N is N - 1
(the first batch of a run, and every run of one batch, goes to a worker), the rest go to
the pool, and the results come back whole wherever they ran."""

from __future__ import annotations

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
