"""Where files live: a local path, or a URI that pyarrow's filesystems open (`s3://`,
`gs://`, `abfs://`, `hdfs://`, `file://`), behind one small interface that every reader and
writer of the replay uses.

A `Location` names a file or a directory. On the local disk (a plain path or a `file://`
URI) its operations are the operating system's: a file is written under a temporary name,
flushed to disk and renamed over the old one, directories are renamed, the writer lock is a
`flock`. Anywhere else they are the filesystem's (`pyarrow.fs`): a file is made in memory
and uploaded whole in one write (an object store shows an object whole or not at all), a
file is moved by copy and delete, and nothing else is renamed (object stores have no atomic
rename of a directory). `Location.local` tells which; the writer takes its commit protocol
from it (`_files.commit_dir`, docs/SCALE.md).

A location prints as given (a path, or the URI with its query, e.g.
`s3://bucket/out?endpoint_override=...`), so the manifest records inputs as the user named
them and a worker on another node reopens a location from its text.
"""

from __future__ import annotations

import atexit
import io
import os
import re
import shutil
import stat
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path, PurePosixPath
from typing import TYPE_CHECKING, BinaryIO
from urllib.parse import quote, unquote, urlsplit

from .._errors import InputError
from ._durable import atomic_file

if TYPE_CHECKING:
    import pyarrow.fs as pafs

_URI = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*://")
_URI_PATH_SAFE = "/=+@,:;!$&'()*~"
"""Characters kept as they are in the path of a URI (the rest is percent-encoded)."""
IMPLICIT_DIRECTORIES = frozenset({"s3", "gcs", "abfs"})
"""pyarrow filesystem types where a directory is a key prefix: nothing to create."""

FilesystemFactory = Callable[[str], "tuple[pafs.FileSystem, str]"]
_FACTORIES: dict[str, FilesystemFactory] = {}
"""URI scheme -> opener, tried before `pyarrow.fs.FileSystem.from_uri` (tests mount a local
directory without renames here to run the object-store protocol on disk)."""
_OPENED: dict[tuple[str, str, str], tuple[pafs.FileSystem, str]] = {}
"""(scheme, host, query) -> the filesystem and the prefix its paths take before the URI's
path (the bucket for `s3://`): one filesystem (one S3 client) per store and process."""
# Dropped at exit before pyarrow finalizes S3 (atexit runs handlers last-registered first):
# an S3 filesystem still referenced then can hang the interpreter's shutdown.
atexit.register(_OPENED.clear)


def _pafs():
    """pyarrow's filesystems, imported when a location not on the local disk is first used
    (a local path needs none of it: `vge metrics` finds its kept answer without pyarrow)."""
    import pyarrow.fs

    return pyarrow.fs


def is_uri(text: str) -> bool:
    return bool(_URI.match(text))


class Location:
    """A file or directory: on the local disk (`local` is its path) or in a pyarrow
    filesystem (`fs` and `path`)."""

    __slots__ = ("fs", "path", "local", "_head", "_url_path", "_query")

    def __init__(
        self,
        fs: pafs.FileSystem | None,
        path: str,
        local: Path | None,
        uri: tuple[str, str, str] | None = None,
    ) -> None:
        self.fs = fs
        self.path = path
        self.local = local
        # a URI as (scheme://host, path as given (percent-encoded), query); None: a path
        self._head, self._url_path, self._query = uri if uri is not None else ("", "", "")

    # ------------------------------------------------------------------ naming

    def __truediv__(self, name: str) -> Location:
        name = name.strip("/")
        local = None if self.local is None else self.local / name
        if not self._head:  # a plain local path
            return Location(None, str(local), local)
        fs_path = f"{self.path.rstrip('/')}/{name}"
        url_path = f"{self._url_path.rstrip('/')}/{quote(name, safe=_URI_PATH_SAFE)}"
        return Location(self.fs, fs_path, local, (self._head, url_path, self._query))

    def joinpath(self, *names: str) -> Location:
        loc = self
        for name in names:
            loc = loc / name
        return loc

    @property
    def name(self) -> str:
        return PurePosixPath(self.path).name

    @property
    def suffix(self) -> str:
        return PurePosixPath(self.path).suffix

    @property
    def stem(self) -> str:
        return PurePosixPath(self.path).stem

    def __str__(self) -> str:
        if not self._head:
            return self.path
        return self._head + self._url_path + (f"?{self._query}" if self._query else "")

    def __repr__(self) -> str:
        return f"Location({str(self)!r})"

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Location) and str(self) == str(other)

    def __lt__(self, other: Location) -> bool:
        return str(self) < str(other)

    def __hash__(self) -> int:
        return hash(str(self))

    def __fspath__(self) -> str:
        """The local path; a location elsewhere has none (`open()` on it fails loudly)."""
        if self.local is None:
            raise TypeError(f"{self}: not on the local disk")
        return str(self.local)

    # ----------------------------------------------------------------- reading

    def _info(self) -> pafs.FileInfo:
        return self.fs.get_file_info(self.path)  # type: ignore[union-attr]

    def exists(self) -> bool:
        if self.local is not None:
            return self.local.exists()
        return self._info().type != _pafs().FileType.NotFound

    def is_dir(self) -> bool:
        if self.local is not None:
            return self.local.is_dir()
        return self._info().type == _pafs().FileType.Directory

    def is_file(self) -> bool:
        if self.local is not None:
            return self.local.is_file()
        return self._info().type == _pafs().FileType.File

    def open_read(self) -> BinaryIO:
        """The file's bytes as a stream (never decompressed on the way). On the local disk
        only a regular file: a device or a pipe may never end, and is read once only."""
        if self.local is not None:
            if not stat.S_ISREG(os.stat(self.local).st_mode):
                raise InputError(
                    str(self), "not a regular file (a device, a pipe or a directory is no input)"
                )
            return open(self.local, "rb")  # noqa: SIM115
        return self.fs.open_input_stream(self.path, compression=None)  # type: ignore[union-attr,return-value]

    def read_bytes(self) -> bytes:
        if self.local is not None:
            return self.local.read_bytes()
        with self.open_read() as fh:
            return fh.read()

    def names(self) -> list[str]:
        """Names of the entries directly in this directory, sorted ([] if there is none)."""
        if self.local is not None:
            try:
                return sorted(p.name for p in self.local.iterdir())
            except (FileNotFoundError, NotADirectoryError):
                return []
        selector = _pafs().FileSelector(self.path, recursive=False, allow_not_found=True)
        return sorted(PurePosixPath(i.path).name for i in self.fs.get_file_info(selector))  # type: ignore[union-attr]

    def files(self) -> list[str]:
        """Paths (relative, `/`-separated) of every file under this directory, sorted."""
        if self.local is not None:
            found = []
            for parent, _, names in os.walk(self.local):
                rel = Path(parent).relative_to(self.local)
                found.extend((rel / n).as_posix() for n in names)
            return sorted(found)
        selector = _pafs().FileSelector(self.path, recursive=True, allow_not_found=True)
        base = len(self.path.strip("/")) + 1  # listed paths may lack the leading "/"
        infos = self.fs.get_file_info(selector)  # type: ignore[union-attr]
        file = _pafs().FileType.File
        return sorted(i.path.lstrip("/")[base:] for i in infos if i.type == file)

    # ----------------------------------------------------------------- writing

    def mkdir(self) -> None:
        """Create this directory and its parents (nothing to do where directories are
        prefixes)."""
        if self.local is not None:
            self.local.mkdir(parents=True, exist_ok=True)
        elif self.fs.type_name not in IMPLICIT_DIRECTORIES:  # type: ignore[union-attr]
            self.fs.create_dir(self.path, recursive=True)  # type: ignore[union-attr]

    @contextmanager
    def writer(self, *, sync: bool = True) -> Iterator[BinaryIO]:
        """Write the whole file through a stream; readers see the old file or the new one.

        Local: `atomic_file` (a temporary file of its own beside it, flushed to disk with
        `sync`, renamed over it; a link there is replaced, not followed).
        Elsewhere: the bytes are made in memory and uploaded in one write when the block
        ends without an error (an error uploads nothing)."""
        if self.local is not None:
            with atomic_file(self.local, sync=sync) as fh:
                yield fh
            return
        buffer = io.BytesIO()
        yield buffer
        self.write_bytes(buffer.getbuffer())

    def write_bytes(self, data: bytes | memoryview) -> None:
        """The file holds `data` (whole, as `writer`)."""
        if self.local is not None:
            with self.writer() as fh:
                fh.write(data)
            return
        parent = self.path.rpartition("/")[0]
        if parent and self.fs.type_name not in IMPLICIT_DIRECTORIES:  # type: ignore[union-attr]
            self.fs.create_dir(parent, recursive=True)  # type: ignore[union-attr]
        stream = self.fs.open_output_stream(self.path, compression=None)  # type: ignore[union-attr]
        stream.write(data)
        stream.close()

    def replace(self, target: Location) -> None:
        """Move this file over `target` (a rename on disk; a copy and a delete elsewhere,
        so `target` changes from the old file to the new one whole)."""
        if self.local is not None and target.local is not None:
            os.replace(self.local, target.local)
            return
        if self.fs is not target.fs:
            raise ValueError(f"cannot move {self} to {target}: not on the same filesystem")
        parent = target.path.rpartition("/")[0]
        if parent and self.fs.type_name not in IMPLICIT_DIRECTORIES:  # type: ignore[union-attr]
            self.fs.create_dir(parent, recursive=True)  # type: ignore[union-attr]
        self.fs.copy_file(self.path, target.path)  # type: ignore[union-attr]
        self.fs.delete_file(self.path)  # type: ignore[union-attr]

    def unlink(self, *, missing_ok: bool = False) -> None:
        """Delete this file (as `Path.unlink`)."""
        if self.local is not None:
            self.local.unlink(missing_ok=missing_ok)
            return
        try:
            self.fs.delete_file(self.path)  # type: ignore[union-attr]
        except FileNotFoundError:
            if not missing_ok:
                raise

    def rmtree(self) -> None:
        """Delete this directory and everything under it, if it exists. On the local disk a
        link (or a file) in its place is removed itself: never followed, so nothing outside
        is touched."""
        if self.local is not None:
            remove_local(self.local)
            return
        if self._info().type == _pafs().FileType.Directory:
            self.fs.delete_dir(self.path)  # type: ignore[union-attr]


def remove_local(path: Path) -> None:
    """Remove a local directory tree, or the link or file in its place (a link is unlinked,
    never followed); a failure names the path (OSError)."""
    if path.is_symlink() or path.is_file():
        path.unlink()
    elif path.exists():
        shutil.rmtree(path)


def confined(root: Location, path: Location) -> bool:
    """Whether `path`, its links followed, is inside the directory `root` (PROTOCOL §1.1: what
    a benchmark names is read from the benchmark). A store has no links: always."""
    return confinement(root)(path)


def confinement(root: Location) -> Callable[[Location], bool]:
    """`confined(root, path)` for many paths: the root and each parent directory resolved
    once (a path resolves component by component, a system call each), then a path whose
    last component is not a link resolves to its parent's resolution and its name."""
    if root.local is None:
        return lambda path: True
    top = os.path.join(os.path.realpath(root.local), "")
    parents: dict[Path, str] = {}

    def inside(path: Location) -> bool:
        local = path.local
        if local is None:
            return True
        if local.name in ("", ".", "..") or local.is_symlink():
            return os.path.realpath(local).startswith(top)
        parent = parents.get(local.parent)
        if parent is None:
            parent = parents[local.parent] = os.path.realpath(local.parent)
        return os.path.join(parent, local.name).startswith(top)

    return inside


def location(given: str | os.PathLike[str] | Location) -> Location:
    """The location named by a local path or a URI; raises `InputError` naming it when no
    filesystem opens the URI (unknown scheme, bad options, unreachable store)."""
    if isinstance(given, Location):
        return given
    text = os.fspath(given)
    if not is_uri(text):
        local = Path(text)
        return Location(None, str(local), local)
    parts = urlsplit(text)
    fs, path = _open(text, parts.scheme, parts.netloc, parts.query, unquote(parts.path))
    local = Path(path) if isinstance(fs, _pafs().LocalFileSystem) else None
    head = f"{parts.scheme}://{parts.netloc}"
    return Location(fs, path, local, (head, parts.path, parts.query))


def _open(
    uri: str, scheme: str, host: str, query: str, url_path: str
) -> tuple[pafs.FileSystem, str]:
    """The filesystem and the path of a URI, reusing the filesystem of a store opened
    before (creating one, for S3 a client, costs far more than the file operation)."""
    key = (scheme, host, query)
    known = _OPENED.get(key)
    if known is not None:
        fs, prefix = known
        return fs, prefix + url_path.rstrip("/")
    factory = _FACTORIES.get(scheme)
    try:
        fs, path = factory(uri) if factory is not None else _pafs().FileSystem.from_uri(uri)
    except (ValueError, OSError) as exc:  # pyarrow's ArrowInvalid is a ValueError
        raise InputError(uri, f"cannot open: {' '.join(str(exc).split())}") from None
    tail = url_path.rstrip("/")
    if path.rstrip("/").endswith(tail):
        _OPENED[key] = (fs, path.rstrip("/")[: len(path.rstrip("/")) - len(tail)])
    return fs, path


__all__ = [
    "IMPLICIT_DIRECTORIES",
    "Location",
    "confined",
    "confinement",
    "is_uri",
    "location",
    "remove_local",
]
