"""Batches as Ray tasks: the batch function local workers run, on every node of a cluster.

The driver keeps a bounded number of tasks in flight (`_executor.in_order`) and takes the
results in order. A task whose worker process or node is lost is run again by Ray (up to
`RETRIES` times); a batch writes only files named by its task, so a retry rewrites the same
bytes and nothing is lost or written twice. Every node must reach the benchmark, the logs
are shipped with the tasks, and the parts are written under OUT: see docs/SCALE.md.
"""

from __future__ import annotations

import os
import signal
from collections import Counter
from typing import Any

from .._errors import ConfigError, WorkerError
from ._quarantine import one_line

RETRIES = 3
"""Times Ray runs a batch again after its worker process or node was lost."""

FAULT_ENV = "VGE_FAULT_KILL_ONCE"
"""Chaos testing: a path; the first batch task that creates it kills its own worker process
(SIGKILL) before working, so the retry path runs (tests/replay/io/test_ray.py)."""


def _on_node(fn: Any, task: Any) -> tuple[str, Any]:
    """`fn(task)` in a Ray worker, with the id of the node it ran on."""
    import ray

    crash = os.environ.get(FAULT_ENV)
    if crash:
        try:
            os.close(os.open(crash, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
        except FileExistsError:
            pass
        else:
            os.kill(os.getpid(), signal.SIGKILL)
    return ray.get_runtime_context().get_node_id(), fn(task)


class RayCluster:
    """Runs batches as Ray tasks on the cluster at `address` (`auto`, `local` or an address)."""

    def __init__(self, address: str) -> None:
        try:
            import ray
        except ImportError:
            raise ConfigError(
                "--ray needs Ray, which is not installed: pip install 'vge-analytics[ray]'"
            ) from None
        self._ray = ray
        self._owned = False
        if not ray.is_initialized():
            try:
                if address == "local":
                    ray.init(include_dashboard=False, log_to_driver=False)
                else:
                    ray.init(address=address, log_to_driver=False)
            except ConnectionError as exc:
                raise ConfigError(
                    f"no Ray cluster at {address!r} ({one_line(str(exc), 160)}); start one "
                    "with `ray start --head`, set RAY_ADDRESS, or use --ray local"
                ) from None
            self._owned = True
        self.slots = max(1, int(ray.cluster_resources().get("CPU", 1)))
        self.nodes: Counter[str] = Counter()
        self._remote = ray.remote(max_retries=RETRIES)(_on_node)

    def submit(self, fn: Any, task: Any) -> Any:
        return self._remote.remote(fn, task)

    def result(self, handle: object) -> Any:
        try:
            node, result = self._ray.get(handle)
        except self._ray.exceptions.RayError as exc:
            raise WorkerError(
                f"a Ray task failed after {RETRIES} retries: {one_line(str(exc), 200)}"
            ) from None
        self.nodes[node] += 1
        return result

    def close(self) -> None:
        if self._owned:
            self._ray.shutdown()
