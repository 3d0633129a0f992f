"""Worker processes end with the process that started them.

Killed with `kill -9`, a parent leaves its pool's workers waiting for tasks that will never
come, and with them the multiprocessing resource tracker, which lives until the last process
holding its pipe has gone. `end_with_parent` (a pool's initializer) ties a worker to its
parent: on Linux the kernel kills the worker when the parent thread that started it ends
(`PR_SET_PDEATHSIG`); elsewhere a thread of the worker notices, within `WATCH_SECONDS`,
that it has another parent. Ray's workers end with their job as Ray ends them."""

from __future__ import annotations

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
