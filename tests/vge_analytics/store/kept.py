"""Helpers of the tests of the files kept in OUT/.metric-cache: a copy of an OUT without
them, the names kept, and files planted in place of a kept one."""

from __future__ import annotations

import os
import shutil
from collections.abc import Callable
from pathlib import Path

import polars as pl

from replay.io import METRIC_CACHE_DIR


def copy_out(out: Path, target: Path) -> Path:
    """A copy of `out` without its cache folder."""
    shutil.copytree(out, target, ignore=shutil.ignore_patterns(METRIC_CACHE_DIR))
    return target


def kept_files(out: Path, pattern: str) -> list[Path]:
    """The files of `pattern` in OUT's cache folder, sorted."""
    folder = out / METRIC_CACHE_DIR
    return sorted(folder.glob(pattern)) if folder.is_dir() else []


def plants(column: str) -> tuple[list[Callable[[Path, Path], object]], list[str]]:
    """(planters, ids) of files that are not ours, put in place of a kept frame whose
    numeric column `column` the code reads: garbage, other columns, `column` as text, a
    FIFO, and a link to a copy whose `column` is 0 (never to be read)."""
    elsewhere = "elsewhere.parquet"

    def link(path: Path, tmp: Path) -> None:
        pl.read_parquet(path).with_columns(pl.lit(0).alias(column)).write_parquet(tmp / elsewhere)
        path.unlink()
        path.symlink_to(tmp / elsewhere)

    planters = [
        lambda path, tmp: path.write_bytes(b"not parquet"),
        lambda path, tmp: pl.DataFrame({"run_id": [1], "other": ["e"]}).write_parquet(path),
        lambda path, tmp: (
            pl.read_parquet(path).with_columns(pl.col(column).cast(pl.String)).write_parquet(path)
        ),
        lambda path, tmp: (path.unlink(), os.mkfifo(path)),
        link,
    ]
    return planters, ["garbage", "other-columns", "text-column", "fifo", "link"]
