"""Byte-identical outputs: the same inputs twice, and with 1 and 2 workers (Parquet, MCAP,
quarantine, manifest), with small batches, row groups and parts so every boundary is hit."""

from __future__ import annotations

import hashlib
import json
import subprocess
import sys
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
import pytest

import replay

from ..conftest import Sample


def _digests(out: Path) -> dict[str, str]:
    return {
        str(p.relative_to(out)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(out.rglob("*"))
        if p.is_file()
    }


@pytest.fixture
def small_boundaries(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("replay.io._job.BATCH_LINES", 5)
    monkeypatch.setattr("replay.io._files.ROW_GROUP_ROWS", 40)


def test_identical_across_repeats_and_workers(
    sample: Sample, tmp_path: Path, small_boundaries: None
) -> None:
    images = replay.BenchImages(str(sample.bench))
    outs = []
    for name, workers in (("a", 1), ("b", 1), ("c", 2)):
        out = tmp_path / name
        replay.replay_runs(
            sample.runs,
            sample.bench,
            out,
            workers=workers,
            mcap=True,
            progress=False,
            image_source=images,
        )
        outs.append(_digests(out))
    assert outs[0] == outs[1] == outs[2]
    names = list(outs[0])
    assert sum(n.endswith(".mcap") for n in names) == 52
    parts = [n for n in names if n.startswith("steps/run_id=vlm-a/")]
    assert len(parts) == 8  # 13 cases x 3 copies = 39 lines, one part per 5 lines
    rows = 0
    for part in parts:
        meta = pq.ParquetFile(tmp_path / "a" / part).metadata
        groups = [meta.row_group(i).num_rows for i in range(meta.num_row_groups)]
        assert groups == [40] * (meta.num_rows // 40) + (
            [meta.num_rows % 40] if meta.num_rows % 40 else []
        )
        rows += meta.num_rows
    assert rows == 240


FORKED = """
import json, sys
import replay
import replay.io._job, replay.io._files, replay.io._runner as runner
replay.io._job.BATCH_LINES = 5
replay.io._files.ROW_GROUP_ROWS = 40
made = []
make = runner.make_executor
def recording(*args, **kwargs):
    executor = make(*args, **kwargs)
    made.append(getattr(executor, "start_method", None))
    return executor
runner.make_executor = recording
bench, out, *runs = sys.argv[1:]
images = replay.BenchImages(bench)
replay.replay_runs(runs, bench, out, workers=2, mcap=True, progress=False, image_source=images)
print(json.dumps(made))
"""


@pytest.mark.skipif(sys.platform != "linux", reason="workers are forked on Linux only")
def test_identical_with_forked_workers(
    sample: Sample, tmp_path: Path, small_boundaries: None
) -> None:
    """`replay_runs` in a process of one thread (as `vge replay` is) forks its workers once
    BENCH is open; they write what one process writes. (pytest-xdist's test processes run
    threads, where the workers are spawned, as above.)"""
    runs = [str(r) for r in sample.runs]
    done = subprocess.run(
        [sys.executable, "-c", FORKED, str(sample.bench), str(tmp_path / "forked"), *runs],
        capture_output=True, text=True, timeout=300, cwd=Path(__file__).parents[3],
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout.splitlines()[-1]) == ["fork"]
    images = replay.BenchImages(str(sample.bench))
    replay.replay_runs(
        sample.runs, sample.bench, tmp_path / "one", mcap=True, progress=False, image_source=images
    )
    forked = _digests(tmp_path / "forked")
    assert forked == _digests(tmp_path / "one")
    assert sum(n.endswith(".mcap") for n in forked) == 52


def _rows(out: Path, table: str) -> pa.Table:
    """A table's rows, part after part (the replay's row order)."""
    parts = sorted((out / table).glob("run_id=*/*.parquet"))
    return pa.concat_tables(pq.read_table(p) for p in parts)


def test_batch_size_changes_only_the_part_layout(
    sample: Sample, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A part holds one batch of lines, so the batch size cuts the files differently; the
    rows, their order, the quarantine and the counts stay the same."""
    outs = []
    for size in (1, 7, 1000):
        monkeypatch.setattr("replay.io._job.BATCH_LINES", size)
        out = tmp_path / str(size)
        replay.replay_runs(sample.runs, sample.bench, out, progress=False)
        outs.append(out)
    for out in outs[1:]:
        for table in ("steps", "episodes", "goals"):
            assert _rows(out, table).equals(_rows(outs[0], table))
        assert (out / "quarantine.jsonl").read_bytes() == (
            outs[0] / "quarantine.jsonl"
        ).read_bytes()
        assert (out / "runs" / "runs.parquet").read_bytes() == (
            outs[0] / "runs" / "runs.parquet"
        ).read_bytes()
        counts = [[r.counts for r in replay.read_manifest(o).runs] for o in (out, outs[0])]
        assert counts[0] == counts[1]
