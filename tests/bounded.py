"""Running what could eat memory under a bound of its own, and measuring what it took.

- `run_bounded(cmd, ...)`: a real process under an address-space limit (`RLIMIT_AS`), its
  stdout read and counted (not kept), its peak resident memory from the kernel (`wait4`).
  It is started by a small launcher process, not forked from the test: Linux counts in a
  process's peak the memory of the process it was forked from (a forked child starts with
  its parent's pages, and `exec` keeps that high-water mark), so a command forked from a
  test worker holding 500 MB would report at least 500 MB whatever it used.
- `TreeMemory(pid)`: samples the peak resident memory (VmHWM) of a process and of every
  process below it, while a block runs (the dashboard's query processes are grandchildren
  of the test, out of reach of `wait4`).

A regression that lifts the limits under test then fails the test (peak far above the
expected bound) instead of taking the machine down: the address-space limit stops it first.
"""

from __future__ import annotations

import os
import resource
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

ADDRESS_SPACE = 3 * 1024**3
"""Default address-space bound of a test process (DuckDB and Python map ~1.5 GB idle)."""


@dataclass(frozen=True)
class Finished:
    returncode: int
    stdout_bytes: int
    stdout_head: bytes
    stderr: str
    peak_memory: int
    """Peak resident memory (bytes)."""
    seconds: float


def run_bounded(
    cmd: Sequence[str], *, address_space: int = ADDRESS_SPACE, timeout: float = 60.0
) -> Finished:
    """Run `cmd` under an address-space bound; stdout is counted (its first KB kept)."""

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (address_space, address_space))

    started = time.monotonic()
    report_read, report_write = os.pipe()
    proc = subprocess.Popen(
        [sys.executable, "-c", _LAUNCHER, str(report_write), *cmd],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        preexec_fn=limit,
        pass_fds=(report_write,),
        start_new_session=True,  # a timeout kills the launcher and the command together
    )
    os.close(report_write)
    counted = {"bytes": 0, "head": b""}
    errors: list[bytes] = []

    def drain_stdout() -> None:
        assert proc.stdout is not None
        while chunk := proc.stdout.read1(1 << 16):
            if len(counted["head"]) < 1024:
                counted["head"] += chunk[: 1024 - len(counted["head"])]
            counted["bytes"] += len(chunk)

    def drain_stderr() -> None:
        assert proc.stderr is not None
        errors.append(proc.stderr.read())

    readers = [threading.Thread(target=drain_stdout), threading.Thread(target=drain_stderr)]
    for reader in readers:
        reader.start()
    deadline = started + timeout
    while True:
        pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
        if pid:
            break
        if time.monotonic() > deadline:
            os.killpg(proc.pid, signal.SIGKILL)
            pid, status, usage = os.wait4(proc.pid, 0)
            break
        time.sleep(0.02)
    seconds = time.monotonic() - started
    for reader in readers:
        reader.join()
    with os.fdopen(report_read, "rb") as fh:
        report = fh.read().split()
    if report:  # the command's own status and peak, as the launcher's wait4 saw them
        status, maxrss = int(report[0]), int(report[1])
    else:  # the launcher was killed (timeout)
        maxrss = usage.ru_maxrss
    proc.returncode = os.waitstatus_to_exitcode(status)
    return Finished(
        returncode=proc.returncode,
        stdout_bytes=counted["bytes"],
        stdout_head=counted["head"],
        stderr=b"".join(errors).decode(errors="replace"),
        peak_memory=maxrss * 1024,
        seconds=seconds,
    )


_LAUNCHER = """
import os, sys
fd, cmd = int(sys.argv[1]), sys.argv[2:]
pid = os.fork()
if pid == 0:
    os.close(fd)
    try:
        os.execvp(cmd[0], cmd)
    finally:
        os._exit(127)
_, status, usage = os.wait4(pid, 0)
os.write(fd, b"%d %d" % (status, usage.ru_maxrss))
"""
"""Forks and execs the command from a process of a few MB, waits for it and reports its
wait status and peak resident memory (KB) on the descriptor it is given."""


def _children(pid: int) -> list[int]:
    """The children of process `pid`; none once it has ended (its /proc entry, or one of its
    threads', can go while it is read)."""
    found = []
    try:
        tasks = list(Path(f"/proc/{pid}/task").glob("*/children"))
    except OSError:
        return found
    for task in tasks:
        try:
            found += [int(c) for c in task.read_text().split()]
        except (OSError, ValueError):
            continue
    return found


def _peak(pid: int) -> int:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) * 1024
    except OSError:
        pass
    return 0


class TreeMemory:
    """Peak resident memory per process of the tree under `pid`, sampled every `every`
    seconds while the `with` block runs; `peaks` maps pid -> bytes."""

    def __init__(self, pid: int, every: float = 0.02) -> None:
        self.pid = pid
        self.every = every
        self.peaks: dict[int, int] = {}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _sample(self) -> None:
        todo = [self.pid]
        while todo:
            pid = todo.pop()
            self.peaks[pid] = max(self.peaks.get(pid, 0), _peak(pid))
            todo += _children(pid)

    def _run(self) -> None:
        while not self._stop.is_set():
            self._sample()
            time.sleep(self.every)

    def __enter__(self) -> TreeMemory:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()
        self._sample()

    def largest_below(self) -> int:
        """The largest peak among the processes below `pid` (0 if none was seen)."""
        return max((v for k, v in self.peaks.items() if k != self.pid), default=0)
