"""Byte-identical outputs: the same inputs twice, and with 1 and 2 workers (Parquet, MCAP,
quarantine, manifest), with small batches, row groups and parts so every boundary is hit."""

from __future__ import annotations

import hashlib
from pathlib import Path

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
    monkeypatch.setattr("replay.io._runner.BATCH_LINES", 5)
    monkeypatch.setattr("replay.io._writer.ROW_GROUP_ROWS", 40)
    monkeypatch.setattr("replay.io._writer.PART_ROWS", 100)


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
    assert len(parts) == 3  # 240 rows in parts of 100
    meta = pq.ParquetFile(tmp_path / "a" / parts[0]).metadata
    assert meta.num_rows == 100 and meta.num_row_groups == 3  # 40 + 40 + 20


def test_batch_size_does_not_change_output(
    sample: Sample, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    outs = []
    for size in (1, 7, 1000):
        monkeypatch.setattr("replay.io._runner.BATCH_LINES", size)
        out = tmp_path / str(size)
        replay.replay_runs(sample.runs, sample.bench, out, progress=False)
        outs.append(_digests(out))
    assert outs[0] == outs[1] == outs[2]
