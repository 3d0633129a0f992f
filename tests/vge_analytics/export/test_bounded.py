"""An export's memory does not grow with the run: exporting a run ten times larger, each
response a long text, takes no more memory beyond the small run's than reading the two runs
does, give or take a few megabytes, and less than the run's text (all measured here, as
real processes under an address-space bound, `tests/bounded.py`).

A reader of Parquet holds a row group's column at a time, whoever reads: the replay writes
a run's steps in parts of up to 4,096 episodes, one row group each. These runs are smaller
than a part, so their steps are rewritten in row groups of 32 episodes, the layout of a run
larger than a part (the full benchmark's runs have four). Reading them is then bounded;
what an export adds to reading is bounded too: a batch of episodes, a recorder buffer of
samples, and (Inspect) the small summary per sample that goes in the log's index."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pyarrow.parquet as pq
import pytest

import vge_analytics as va

from ..conftest import HAND, replay_to, write_bench, write_run
from .reading import read_command

ROOT = Path(__file__).resolve().parents[3]
SMALL, LARGE = 60, 600
"""Episodes of the two runs: the large one holds 600 x 7 responses of about 32 kB (140 MB of
text) and a structured action each. Reading streams, so what it needs beyond the small run is
the scans' read-ahead and what the allocators keep (80-140 MB measured, whatever the run's
size): the run's text must be well above that for the floor's test to tell streaming from
holding."""
ADDRESS_SPACE = 6 * 1024**3
"""The safety net: DuckDB's and zstd's threads reserve address space far beyond what they
use (the test asserts resident memory)."""
ROW_GROUP_STEPS = 8 * 32
"""Steps per row group of the rewritten runs: 32 episodes."""
HEADROOM = 48 * 1024**2
"""What the large export may grow beyond the growth of reading: the Inspect recorder's
summaries of the 540 more samples (about 10 kB each), and the slack of the allocators of
DuckDB and Arrow, which scan the tables as Arrow datasets with two files read ahead (the
large run's steps are in several parts: its 280 MB of responses and thinking pass the replay's
32 MiB per part)."""


def _long_run(root: Path, n: int) -> Path:
    """OUT of one run of `n` copies of the kettle_c episode (three goals, eight steps), each
    response's thinking lengthened to ~32 kB."""
    doc = json.loads((HAND / "kettle_c_parse_multigoal_chain.json").read_text())
    tasks = [dict(doc["task"], episode_id=f"long-{i:04d}") for i in range(n)]
    bench = write_bench(root, [doc], tasks)
    episodes = []
    for i in range(n):
        steps = []
        for k, step in enumerate(doc["episode"]["steps"]):
            if "output" in step:
                filler = " ".join(
                    f"I look closely at part {i}-{k}-{w} of the kettle." for w in range(660)
                )
                step = {"output": step["output"].replace("Thinking: ", f"Thinking: {filler} ", 1)}
            steps.append(step)
        episodes.append({"episode_id": f"long-{i:04d}", "steps": steps})
    header = {"run_id": "long", "model": "model-l", "agent_kind": "vlm", "lambda": 2}
    out = replay_to(root / "out", [write_run(root, header, episodes)], bench)
    for part in (out / "steps").rglob("*.parquet"):
        pq.write_table(pq.read_table(part), part, row_group_size=ROW_GROUP_STEPS)
    return out


@pytest.fixture(scope="module")
def long_outs(tmp_path_factory) -> dict[int, Path]:
    return {n: _long_run(tmp_path_factory.mktemp(f"long{n}"), n) for n in (SMALL, LARGE)}


LAUNCHER = """
import json, sys
from tests.bounded import run_bounded
done = run_bounded(json.loads(sys.argv[1]), address_space=int(sys.argv[2]), timeout=600)
print(json.dumps([done.returncode, done.peak_memory, done.stderr + done.stdout_head.decode()]))
"""
"""`run_bounded` in a small process of its own: the kernel counts in a child's peak what it
shared with its parent when it was forked, so the test process, grown by building the
runs, would be everybody's peak."""


def _peak(cmd: list[str], expected: str, runs: int = 3) -> int:
    """The least peak of `runs` runs: DuckDB's and Arrow's threads read ahead as the machine
    lets them, so one run's peak varies by tens of MB on a loaded machine; the least is the
    memory the command needs."""
    peaks = []
    for _ in range(runs):
        launcher = [sys.executable, "-c", LAUNCHER, json.dumps(cmd), str(ADDRESS_SPACE)]
        launched = subprocess.run(launcher, capture_output=True, text=True, cwd=ROOT, check=True)
        returncode, peak, text = json.loads(launched.stdout)
        assert returncode == 0, text
        assert expected in text, text
        peaks.append(peak)
    return min(peaks)


@pytest.fixture(scope="module")
def reading(long_outs) -> dict[int, int]:
    """Peak memory of reading each run with nothing written."""
    return {n: _peak(read_command(out), f"read {n} episodes") for n, out in long_outs.items()}


@pytest.mark.parametrize("fmt", ["inspect", "atif"])
def test_memory_does_not_grow_with_the_run(long_outs, reading, tmp_path, fmt):
    peaks = {}
    for n, out in long_outs.items():
        cmd = [sys.executable, "-m", "vge_analytics.cli", "export", str(out), "--format", fmt]
        cmd += ["--out", str(tmp_path / str(n)), "--images", "none"]
        peaks[n] = _peak(cmd, f"{n} episodes, {8 * n:,} steps")
    written = sum(p.stat().st_size for p in (tmp_path / str(LARGE)).rglob("*") if p.is_file())
    responses = va.steps(long_outs[LARGE], columns=["output"])["output"].str.len_bytes().sum()
    assert responses > 130 * 10**6
    if fmt == "atif":  # every response went through, whole
        assert written > responses
    grown = peaks[LARGE] - peaks[SMALL]
    read = reading[LARGE] - reading[SMALL]
    measured = {"export": peaks, "read": reading}
    assert grown <= read + HEADROOM, measured
    # Holding the run's responses (the steps as rows, what a reader that does not stream
    # does) takes them twice at least: Arrow's copy and Python's strings. Reading, the floor
    # the export is measured against, must not.
    assert read < 2 * responses, measured
