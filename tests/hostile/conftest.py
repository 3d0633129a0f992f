"""Fixtures of the hostile-input tests."""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import pytest


@dataclass(frozen=True)
class Ran:
    returncode: int
    stdout: str
    stderr: str
    seconds: float


@pytest.fixture
def vge_here(capsys: pytest.CaptureFixture[str]):
    """`vge` in this process (what needs no memory bound: no start-up paid)."""
    from vge_analytics.cli import main

    def run(*args: str | Path | int) -> Ran:
        capsys.readouterr()
        started = time.monotonic()
        code = main([str(a) for a in args])
        seconds = time.monotonic() - started
        shown = capsys.readouterr()
        return Ran(code, shown.out, shown.err, seconds)

    return run
