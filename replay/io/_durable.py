"""Files that a crash cannot leave half-written, for the run directories the live tools write
(`vge run`, `vge play`): records appended whole and synced, files replaced by a rename."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path


def write_all(fd: int, data: bytes) -> None:
    """Write the whole of `data` to `fd`, then fsync: a crash leaves a prefix of it at worst
    (a short write, which only a full disk gives, is continued; the next one then fails)."""
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view) :]
    os.fsync(fd)


def append_record(path: Path, data: bytes, *, create: bool = False) -> None:
    """Append `data` (whole lines) to `path` in one write and make it durable; after a crash
    the file ends with whole lines, or with one cut short that its reader drops."""
    flags = os.O_WRONLY | os.O_APPEND | (os.O_CREAT if create else 0)
    fd = os.open(path, flags, 0o644)
    try:
        write_all(fd, data)
    finally:
        os.close(fd)


def write_atomic(path: Path, data: bytes) -> None:
    """Create or replace `path` whole or not at all: a temporary file in the same directory,
    synced, renamed over it, the directory synced."""
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        try:
            write_all(fd, data)
        finally:
            os.close(fd)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    fsync_dir(path.parent)


def truncate(path: Path, size: int) -> None:
    """Cut `path` to `size` bytes (a torn last record), durably."""
    with open(path, "r+b") as fh:
        fh.truncate(size)
        fh.flush()
        os.fsync(fh.fileno())


def fsync_dir(path: Path) -> None:
    """Make a file's creation, rename or removal in directory `path` durable."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


__all__ = ["append_record", "fsync_dir", "truncate", "write_all", "write_atomic"]
