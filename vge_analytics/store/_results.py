"""Results kept beside OUT: what a page of the dashboard computed from OUT, read back by the
next server on the same OUT instead of being computed again (docs/METRICS.md, The metric cache).

A result (a frame, a number, a list of values, a tuple of those) is a function of OUT's tables,
the function's arguments, the metric definitions it was given and the analytics' code. Its
file, `OUT/.metric-cache/result-<contents>-<key>.arrow` (`replay.io.result_cache_path`), is
named by all of them: `<contents>` is the store's `contents_key` (the manifest's sha256 and the
size and modification time of every table file), `<key>` a hash of the function's name, its
arguments, the caller's `version` (the metric definitions) and the code of `replay` and
`vge_analytics` (`code_key`). Whatever changes names another file; nothing stale is read.

The file is an Arrow IPC file written by polars (its dtypes, enums included, come back as they
were), the value's shape in its schema's metadata: the same value, bit for bit, is read back.
A value of another kind (a record, an object) is not kept. Bounds: a result over
`MAX_RESULT_BYTES` is not kept and a file over it is not read; at most `MAX_RESULTS` files are
kept (the oldest go), and a write removes the results kept for other contents. Nothing is kept
for an OUT in memory or object storage, without a manifest, or whose cache folder is a link; a
file that is a link is not read; an OUT that cannot be written computes every time.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
from collections.abc import Callable
from functools import cache
from pathlib import Path
from typing import Any, TypeVar

import polars as pl
import pyarrow as pa

from replay import OutputError
from replay.io import atomic_file, result_cache_path

from ._kept import own_folder
from ._store import open_store

T = TypeVar("T")

MAX_RESULT_BYTES = 64 << 20
"""The largest result kept (its frame's size in memory, and its file's size)."""

MAX_RESULTS = 512
"""Result files kept in one OUT's cache folder (the oldest are removed past it)."""

_META = b"vge-result"
"""The schema metadata key holding the value's shape and what it was computed from."""


class _NotKept(Exception):
    """A value (or argument) of a kind this cache does not write."""


def _shape(value: Any, frames: list[pl.DataFrame]) -> Any:
    """`value` as JSON with its kinds tagged (a tuple stays a tuple, a dict keeps its order);
    a frame becomes a reference to `frames`, where it is appended (at most one)."""
    if isinstance(value, pl.DataFrame):
        if frames:
            raise _NotKept("two frames")
        frames.append(value)
        return ["frame"]
    if value is None or isinstance(value, (bool, int, str)):
        return ["v", value]
    if isinstance(value, float):
        return ["float", value.hex()]  # every float, NaN and infinities too, bit for bit
    if isinstance(value, (tuple, list)):
        return ["tuple" if isinstance(value, tuple) else "list", [_shape(v, frames) for v in value]]
    if isinstance(value, dict) and all(isinstance(k, str) for k in value):
        return ["dict", [[k, _shape(v, frames)] for k, v in value.items()]]
    raise _NotKept(type(value).__name__)


def _value(shape: Any, frame: pl.DataFrame | None) -> Any:
    """The value `_shape` described."""
    kind = shape[0]
    if kind == "frame":
        if frame is None:
            raise _NotKept("no frame")
        return frame
    if kind == "v":
        return shape[1]
    if kind == "float":
        return float.fromhex(shape[1])
    if kind in ("tuple", "list"):
        items = [_value(s, frame) for s in shape[1]]
        return tuple(items) if kind == "tuple" else items
    if kind == "dict":
        return {k: _value(s, frame) for k, s in shape[1]}
    raise _NotKept(str(kind))


@cache
def code_key() -> str:
    """A hash of the sources of `replay` and `vge_analytics` (their Python, SQL and Cython
    files): another version of the code computes its results afresh."""
    h = hashlib.sha256()
    for package in ("replay", "vge_analytics"):
        root = Path(__file__).resolve().parents[2] / package
        for path in sorted(root.rglob("*")):
            if path.suffix in (".py", ".sql", ".pyx", ".pxd") and path.is_file():
                h.update(f"\0{path.relative_to(root).as_posix()}\0".encode())
                h.update(path.read_bytes())
    return h.hexdigest()[:16]


def _key(name: str, arguments: Any, version: str) -> str:
    doc = json.dumps([name, _shape(arguments, []), version, code_key()])
    return hashlib.sha256(doc.encode()).hexdigest()[:16]


def _read(path: Path) -> tuple[bool, Any]:
    """(True, the value kept at `path`) or (False, None) when there is none to read (absent, a
    link, too large, unreadable, or not a result)."""
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
    except OSError:
        return False, None
    try:
        with os.fdopen(fd, "rb") as fh:
            data = fh.read(MAX_RESULT_BYTES + 1)
        if len(data) > MAX_RESULT_BYTES:
            return False, None
        reader = pa.ipc.open_file(pa.py_buffer(data))
        shape = json.loads((reader.schema.metadata or {})[_META])
        frame = pl.read_ipc(io.BytesIO(data)) if shape[0] == ["frame"] else None
        return True, _value(shape[1], frame)
    except (OSError, KeyError, ValueError, TypeError, IndexError, pa.ArrowException, _NotKept):
        return False, None
    except pl.exceptions.PolarsError:
        return False, None


def _write(path: Path, value: Any) -> None:
    """Keep `value` at `path` (nothing when it is of another kind or too large)."""
    frames: list[pl.DataFrame] = []
    shape = _shape(value, frames)
    frame = frames[0] if frames else pl.DataFrame()
    if frame.estimated_size() > MAX_RESULT_BYTES:
        return
    raw = io.BytesIO()
    frame.write_ipc(raw, compression="zstd")
    table = pa.ipc.open_file(pa.py_buffer(raw.getvalue())).read_all()
    meta = json.dumps([["frame"] if frames else ["none"], shape]).encode()
    table = table.replace_schema_metadata({**(table.schema.metadata or {}), _META: meta})
    sink = pa.BufferOutputStream()
    with pa.ipc.new_file(sink, table.schema) as writer:
        writer.write_table(table)
    data = sink.getvalue().to_pybytes()
    if len(data) > MAX_RESULT_BYTES:
        return
    path.parent.mkdir(exist_ok=True)
    with atomic_file(path, sync=False) as fh:
        fh.write(data)


def _prune(path: Path) -> None:
    """Remove the results kept for other contents of OUT, and the oldest past `MAX_RESULTS`."""
    contents = path.name.split("-")[1]
    kept = []
    for old in path.parent.glob("result-*.arrow"):
        with contextlib.suppress(OSError):
            if old.name.split("-")[1] != contents:
                old.unlink()
            else:
                kept.append((old.lstat().st_mtime_ns, old.name, old))
    for _, _, old in sorted(kept)[: max(0, len(kept) - MAX_RESULTS)]:
        with contextlib.suppress(OSError):
            old.unlink()


def kept_result(
    out: str | Path, name: str, arguments: Any, compute: Callable[[], T], *, version: str = ""
) -> T:
    """`compute()`, the result `name(OUT, *arguments)` gives, read from OUT's cache folder when
    kept there for OUT's contents, `arguments`, `version` (what else the result depends on,
    such as the metric definitions) and this code; otherwise computed and kept."""
    store = open_store(out)
    where = store.out
    if store.contents is None or not isinstance(where, Path) or not own_folder(where):
        return compute()
    try:
        path = result_cache_path(where, store.contents, _key(name, arguments, version))
    except _NotKept:
        return compute()
    found, value = _read(path)
    if found:
        return value
    value = compute()
    with contextlib.suppress(
        OSError, OutputError, _NotKept, pa.ArrowException, pl.exceptions.PolarsError
    ):
        _write(path, value)
        _prune(path)
    return value


__all__ = ["MAX_RESULTS", "MAX_RESULT_BYTES", "code_key", "kept_result"]
