"""How long a worker process of `vge replay` lives, and how it starts.

- `start_worker` (a pool's initializer) ties a worker to the process that started it and,
  given BENCH, opens it at once unless it has it from its parent (`WorkerProcesses`).
- `end_with_parent` does the tying. Killed with `kill -9`, a parent leaves its pool's
  workers waiting for tasks that will never come, and with them a spawned pool's
  multiprocessing resource tracker, which lives until the last process holding its pipe
  has gone: on Linux the kernel kills the worker when the parent thread that started it
  ends (`PR_SET_PDEATHSIG`); elsewhere a thread of the worker notices, within
  `WATCH_SECONDS`, that it has another parent. Ray's workers end with their job as Ray
  ends them.

Light on purpose (the standard library only): the executor imports it, and a caller may
make an executor before it imports the rest of the engine.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import signal
import sys
import threading
import time

PR_SET_PDEATHSIG = 1
"""prctl(2) option: the signal a process receives when its parent ends (linux/prctl.h)."""
WATCH_SECONDS = 1.0
"""How often the watch thread, where there is no PR_SET_PDEATHSIG, checks the parent."""


def start_worker(parent: int, bench: str | None = None) -> None:
    """A pool worker's initializer: end with process `parent` and, given BENCH, open it now
    rather than when the first batch arrives (a forked worker has it already, from its
    parent). Opening it imports nearly all a batch needs (the rules, the kernel, pyarrow,
    msgspec: 0.17 of the 0.18 s the batch module takes), and the imports are most of a
    spawned worker's start."""
    end_with_parent(parent)
    if bench is not None:
        from .._errors import VGEError
        from ._worker import worker_state

        with contextlib.suppress(VGEError):  # the first batch opens it again and says why
            worker_state(bench)


def end_with_parent(parent: int, *, death_signal: bool = sys.platform == "linux") -> None:
    """Make this process end when process `parent` does (a pool's worker, given the pool
    owner's pid); `death_signal=False` uses the watch thread."""
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
