"""The metrics do not depend on the order in which rows are read: the same tables, their rows
reversed and split over several files and row groups (as another machine's threads, another
writer or object storage may deliver them), give bit-identical values. Sums of fractions are
taken with DuckDB's compensated `fsum`, whose result does not drift with the order of its
terms as a plain floating-point `sum` does."""

from __future__ import annotations

import shutil
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

import vge_analytics as va


def _reordered_copy(out: Path, target: Path, pieces: int = 3) -> Path:
    shutil.copytree(out / "runs", target / "runs")
    for table in ("steps", "episodes", "goals"):
        for part in sorted((out / table).rglob("*.parquet")):
            rows = pq.read_table(part)
            rows = rows.take(pa.array(range(rows.num_rows - 1, -1, -1)))
            folder = target / part.parent.relative_to(out)
            folder.mkdir(parents=True, exist_ok=True)
            size = -(-rows.num_rows // pieces)
            for k in range(pieces):
                piece = rows.slice(k * size, size)
                pq.write_table(piece, folder / f"piece-{k}.parquet", row_group_size=97)
    return target


def test_metrics_are_bit_identical_whatever_the_row_order(sample_out: Path, tmp_path: Path):
    copy = _reordered_copy(sample_out, tmp_path / "reordered")
    by = ["run_id", "category"]  # many small groups and a few large ones
    for grouping in (["run_id"], by):
        want = va.metrics(sample_out, by=grouping)
        got = va.metrics(copy, by=grouping)
        assert got.equals(want), grouping
