"""The floor of an export: a process that reads every selected episode of OUT as `vge export`
does (`vge_analytics.export._source`: rows, goals and steps a batch at a time) and writes
nothing. Its time and memory are what any export pays before it writes a byte (the memory
test and `benchmarks/bench_export.py` measure against it)."""

from __future__ import annotations

import sys
from pathlib import Path

READ_ALL = """
import sys
from vge_analytics.export._source import open_source
runs = sys.argv[2].split(",") if len(sys.argv) > 2 and sys.argv[2] else None
source = open_source(sys.argv[1], runs=runs)
steps = sum(len(e.steps) for run in source.runs for e in source.episodes_of(run))
print(f"read {source.episodes} episodes, {steps} steps")
"""


def read_command(out: Path, runs: str = "") -> list[str]:
    """The command of that process."""
    return [sys.executable, "-c", READ_ALL, str(out), runs]
