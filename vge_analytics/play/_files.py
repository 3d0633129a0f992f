"""Writing a human run so that a crash loses nothing shown: whole records in one write and
`fsync`, new files renamed into place, journals read back up to their last whole line."""

from __future__ import annotations

import os
from pathlib import Path

import orjson

from .._errors import PlayError


def append_record(path: Path, data: bytes) -> None:
    """Append `data` to `path` with one write and make it durable."""
    fd = os.open(path, os.O_WRONLY | os.O_APPEND)
    try:
        write_all(fd, data, path)
    finally:
        os.close(fd)


def write_all(fd: int, data: bytes, path: Path) -> None:
    """One write of a whole record, then fsync: a crash leaves a prefix of it at worst."""
    written = os.write(fd, data)
    if written != len(data):  # a full disk; the torn line is cut off when next opened
        raise PlayError(f"{path}: only {written} of {len(data)} bytes could be written")
    os.fsync(fd)


def write_new(path: Path, data: bytes) -> None:
    """Create `path` whole or not at all: written under a temporary name, then renamed."""
    tmp = path.with_name(f".{path.name}.tmp")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
    try:
        write_all(fd, data, tmp)
    finally:
        os.close(fd)
    os.replace(tmp, path)
    fsync_dir(path.parent)


def truncate(path: Path, size: int) -> None:
    with open(path, "r+b") as fh:
        fh.truncate(size)
        fh.flush()
        os.fsync(fh.fileno())


def fsync_dir(path: Path) -> None:
    """Make a file's creation, rename or removal in `path` durable."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def journal_header(path: Path) -> str | None:
    """The episode id a journal's first line names (None if it cannot be read)."""
    try:
        with open(path, "rb") as fh:
            first = fh.readline()
        head = orjson.loads(first)
    except (OSError, orjson.JSONDecodeError):
        return None
    episode_id = head.get("episode_id") if isinstance(head, dict) else None
    return episode_id if isinstance(episode_id, str) else None


def journal_steps(path: Path) -> tuple[list[dict], int]:
    """The steps of a journal and the byte size they end at. A last line without its
    newline is a write the app died in (its feedback was never shown) and is left out; a
    complete line that is not a step cannot come from a crash and is an error."""
    data = path.read_bytes()
    steps: list[dict] = []
    pos = data.find(b"\n") + 1  # after the header line
    while pos > 0:
        end = data.find(b"\n", pos)
        if end < 0:
            break
        try:
            step = orjson.loads(data[pos:end])
        except orjson.JSONDecodeError:
            step = None
        if not isinstance(step, dict) or not isinstance(step.get("action"), dict):
            raise PlayError(f"{path}: line {len(steps) + 2} is not a step; discard the episode")
        steps.append(step)
        pos = end + 1
    return steps, pos


__all__ = [
    "append_record",
    "fsync_dir",
    "journal_header",
    "journal_steps",
    "truncate",
    "write_all",
    "write_new",
]
