"""The processes a process leaves behind, from /proc (Linux): for the tests and the benchmark
of a killed replay."""

from __future__ import annotations

import time
from pathlib import Path

from tests.bounded import _children as children  # its pids, from /proc/<pid>/task/*/children


def alive(pid: int) -> bool:
    """Whether `pid` runs (a zombie has ended; only its parent has not collected it)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat[stat.rindex(")") + 2] != "Z"


def left_after(pids: list[int], seconds: float) -> list[int]:
    """The processes of `pids` still alive once they all ended or `seconds` passed."""
    deadline = time.monotonic() + seconds
    while any(map(alive, pids)) and time.monotonic() < deadline:
        time.sleep(0.05)
    return [p for p in pids if alive(p)]


__all__ = ["alive", "children", "left_after"]
