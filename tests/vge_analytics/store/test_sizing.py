"""The default memory limit of a command's queries, sized from OUT (`store._sizing`)."""

from __future__ import annotations

import os
from pathlib import Path

from vge_analytics.store import _sizing, sized_memory_limit, table_bytes

MB = 1024**2


def _out(root: Path) -> Path:
    """An OUT whose tables hold 2 MB + 1 MB + 3 bytes, beside files that are not its tables."""
    (root / "steps" / "run_id=a").mkdir(parents=True)
    (root / "steps" / "run_id=a" / "part-0.parquet").write_bytes(b"s" * (2 * MB))
    (root / "runs").mkdir()
    (root / "runs" / "runs.parquet").write_bytes(b"r" * MB)
    (root / "episodes" / "run_id=a").mkdir(parents=True)
    (root / "episodes" / "run_id=a" / "part-0.parquet").write_bytes(b"e" * 3)
    (root / "manifest.json").write_bytes(b"m" * MB)  # not a table
    (root / ".metric-cache").mkdir()
    (root / ".metric-cache" / "x.parquet").write_bytes(b"c" * MB)  # not a table
    return root


def test_the_tables_bytes_and_the_sized_default(tmp_path: Path):
    out = _out(tmp_path / "out")
    assert table_bytes(out) == 3 * MB + 3
    assert table_bytes(f"file://{out}") == 3 * MB + 3
    # 512 MB plus half of 3 MB + 3 bytes (rounded down), worked by hand
    assert sized_memory_limit(out, None) == 512 * MB + 1572865
    assert sized_memory_limit(out, "2GB") == "2GB"  # given: as given


def test_links_are_not_followed(tmp_path: Path):
    out = _out(tmp_path / "out")
    big = tmp_path / "elsewhere.bin"
    big.write_bytes(b"x" * (4 * MB))
    os.symlink(big, out / "steps" / "run_id=a" / "link.parquet")
    os.symlink(tmp_path, out / "goals")  # a linked table folder: not walked
    assert table_bytes(out) == 3 * MB + 3


def test_at_most_the_machine_share(tmp_path: Path, monkeypatch):
    out = _out(tmp_path / "out")
    monkeypatch.setattr(_sizing, "default_memory_limit", lambda: 513 * MB)
    assert sized_memory_limit(out, None) == 513 * MB
    assert sized_memory_limit(tmp_path / "missing", None) == 512 * MB  # no tables: the floor


def test_unlisted_storage_takes_the_machine_share(monkeypatch):
    monkeypatch.setattr(_sizing, "default_memory_limit", lambda: 700 * MB)
    assert table_bytes("nosuchscheme://bucket/out") is None
    assert sized_memory_limit("nosuchscheme://bucket/out", None) == 700 * MB
