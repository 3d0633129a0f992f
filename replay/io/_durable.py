"""Files that a crash cannot leave half-written and that no symbolic link can redirect: the
one atomic writer of the project (the replay's outputs, the run directories `vge run` and
`vge play` write, the exports, the caches), records appended whole and synced.

A file is replaced whole, never through a link:

- it is written under a temporary name of its own in the destination's folder, created with
  `O_CREAT | O_EXCL | O_NOFOLLOW` (a name nobody else holds, and never a link someone left
  there), with the permissions a new file gets (the umask's);
- then renamed over the destination: a rename replaces a symbolic link at the destination
  itself, it never writes through it (the link's target is left as it was);
- with `sync` (the default) the file is flushed to disk before the rename and the folder
  after it, so after a power loss the destination holds the old bytes or the new ones. The
  exports pass `sync=False`: they write up to tens of thousands of files, which a rerun
  writes again, and a sync each would cost more than the rest of the export.

Folders a writer makes inside a destination it was given (`make_folders`) are made with
`mkdir`; one found there already must be a folder, not a symbolic link to one, or the writer
stops with one line naming it.
"""

from __future__ import annotations

import errno
import os
import secrets
import shutil
import stat
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import BinaryIO

from .._errors import ConfigError, OutputError

_CREATE = os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC
_FULL = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EFBIG})
"""What a full disk, a quota or a file-size limit raises: the output file is named."""
_ATTEMPTS = 100
"""Temporary names tried before giving up (each a random 64-bit suffix: one is enough)."""


def write_all(fd: int, data: bytes) -> None:
    """Write the whole of `data` to `fd`, then fsync: a crash leaves a prefix of it at worst
    (a short write, which only a full disk gives, is continued; the next one then fails)."""
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view) :]
    os.fsync(fd)


def append_record(path: Path, data: bytes, *, create: bool = False) -> None:
    """Append `data` (whole lines) to `path` in one write and make it durable; after a crash
    the file ends with whole lines, or with one cut short that its reader drops. A symbolic
    link at `path` is not followed (the append fails)."""
    flags = os.O_WRONLY | os.O_APPEND | os.O_NOFOLLOW | (os.O_CREAT if create else 0)
    fd = os.open(path, flags, 0o644)
    try:
        write_all(fd, data)
    except OSError as exc:
        raise output_error(path, exc) from exc
    finally:
        os.close(fd)


def _temporary(path: Path) -> tuple[int, Path]:
    """A new file beside `path`, open for writing, under a name no one else holds."""
    stem = path.name[:200]  # the suffix fits any name the file system takes
    for _ in range(_ATTEMPTS):
        tmp = path.with_name(f".{stem}.{secrets.token_hex(8)}.tmp")
        try:
            return os.open(tmp, _CREATE, 0o666), tmp
        except FileExistsError:
            continue
    raise FileExistsError(f"{path.parent}: no free temporary name for {path.name}")


def _publish(tmp: Path, path: Path, sync: bool) -> None:
    """Rename `tmp` over `path` (a link at `path` is replaced, not followed); with `sync`,
    the folder's entry is made durable."""
    os.replace(tmp, path)
    if sync:
        fsync_dir(path.parent)


class FileSet:
    """Files written whole under temporary names beside their destinations, then renamed in
    together by `commit`, in the order they were written (or removed by `discard`): what
    fails while they are written (a full disk, a late error) changes none of them. With
    `sync`, each is flushed to disk before the renames and its folder after them."""

    def __init__(self, *, sync: bool = True) -> None:
        self.sync = sync
        self._written: list[tuple[Path, Path]] = []

    @contextmanager
    def file(self, path: Path) -> Iterator[BinaryIO]:
        """A stream to write `path` through; it is held back until `commit`."""
        fd, tmp = _temporary(path)
        try:
            with os.fdopen(fd, "wb") as fh:
                yield fh
                if self.sync:
                    fh.flush()
                    os.fsync(fh.fileno())
        except OSError as exc:
            tmp.unlink(missing_ok=True)
            raise output_error(path, exc) from exc
        except BaseException:
            tmp.unlink(missing_ok=True)
            raise
        self._written.append((tmp, path))

    def commit(self) -> None:
        """Rename every file written over its destination (a link there is replaced, not
        followed); renames take no space, so a full disk cannot stop them half-way."""
        for tmp, path in self._written:
            os.replace(tmp, path)
        if self.sync:
            for folder in dict.fromkeys(path.parent for _, path in self._written):
                fsync_dir(folder)
        self._written.clear()

    def discard(self) -> None:
        for tmp, _ in self._written:
            tmp.unlink(missing_ok=True)
        self._written.clear()


@contextmanager
def atomic_file(path: Path, *, sync: bool = True) -> Iterator[BinaryIO]:
    """A file to write `path` through: the block writes a temporary file beside it, which
    replaces `path` when the block ends without an error (and is removed when it does not).
    `sync`: flushed to disk before the rename, the folder after it. A full disk raises an
    `OutputError` naming `path`."""
    files = FileSet(sync=sync)
    with files.file(path) as fh:
        yield fh
    files.commit()


def output_error(path: Path | str, exc: OSError) -> OSError | OutputError:
    """A full disk (a quota, a file-size limit) while writing `path` as one line naming it;
    another error as it was."""
    code = exc.errno
    if code is None and "No space left" in str(exc):  # pyarrow keeps only the message
        code = errno.ENOSPC
    if code not in _FULL:
        return exc
    return OutputError(str(path), f"cannot write: {os.strerror(code)}")


def write_atomic(path: Path, data: bytes, *, sync: bool = True) -> None:
    """Create or replace `path` with `data`, whole or not at all, never through a link
    (`atomic_file`)."""
    with atomic_file(path, sync=sync) as fh:
        fh.write(data)


@contextmanager
def staged_path(path: Path, *, sync: bool = True) -> Iterator[Path]:
    """A path for a writer that opens its file by name (a library's): it lies in a private
    folder made for it beside `path` (by `mkdtemp`: new, this user's alone), and replaces
    `path` when the block ends without an error; the folder is removed either way."""
    folder = Path(tempfile.mkdtemp(prefix=".staged.", dir=path.parent))
    try:
        staged = folder / path.name  # the same name: a library may read its kind from it
        yield staged
        if sync:
            fd = os.open(staged, os.O_RDONLY | os.O_NOFOLLOW)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)
        _publish(staged, path, sync)
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def make_folders(base: Path, *parts: str) -> Path:
    """`base/parts...`, each part made with `mkdir` where missing; one that exists must be a
    folder, not a symbolic link (a writer writes only into folders it can see are real).
    `base` is the destination as the user named it. Raises `ConfigError` naming the link."""
    folder = base
    for part in parts:
        folder = folder / part
        try:
            os.mkdir(folder)
        except FileExistsError:
            mode = os.lstat(folder).st_mode
            if stat.S_ISLNK(mode):
                raise ConfigError(
                    f"{folder}: a symbolic link where a folder is written; nothing is written "
                    "through a link: remove it, or write elsewhere"
                ) from None
            if not stat.S_ISDIR(mode):
                raise ConfigError(f"{folder}: not a folder, where a folder is written") from None
    return folder


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


__all__ = [
    "append_record",
    "atomic_file",
    "fsync_dir",
    "make_folders",
    "staged_path",
    "truncate",
    "write_all",
    "write_atomic",
]
