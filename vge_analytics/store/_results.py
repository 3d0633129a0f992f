"""Results kept beside OUT: what a page of the dashboard computed from OUT, read back by the
next server on the same OUT instead of being computed again (docs/METRICS.md, The metric cache).

A result (a frame, a number, a list of values, a tuple of those) is a function of OUT's tables,
the function's arguments, the metric definitions it was given and the analytics' code. Its
file, `OUT/.metric-cache/result-<contents>-<key>.arrow` (`replay.io.result_cache_path`), is
named by all of them: `<contents>` is the store's `contents_key` (the manifest's sha256 and the
size and modification time of every table file), `<key>` a hash of the function's name, its
arguments, the caller's `version` (the metric definitions) and the code of `replay` and
`vge_analytics` (`code_key`). Whatever changes names another file; nothing stale is read.

The file is an Arrow IPC file with a row per frame of the value, each as polars writes it
(its dtypes, enums included, come back as they were), and the value's shape in the schema's
metadata: the same value, bit for bit, is read back. A value may be a frame, a number, a
string, a list, tuple or dict of those, or a dataclass of `replay` or `vge_analytics` (found
by its name among the modules loaded, made again from its fields); another kind is not kept. Bounds: a result over
`MAX_RESULT_BYTES` is not kept and a file over it is not read; at most `MAX_RESULTS` files are
kept (the oldest go), and a write removes the results kept for other contents. Nothing is kept
for an OUT in memory or object storage, without a manifest, or whose cache folder is a link; a
file that is a link is not read; an OUT that cannot be written computes every time.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import io
import json
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import polars as pl
import pyarrow as pa

from replay import OutputError
from replay.io import atomic_file, result_cache_path

from ._code import code_key
from ._kept import own_folder, prune_kept, read_kept
from ._store import open_store

T = TypeVar("T")

MAX_RESULT_BYTES = 64 << 20
"""The largest result kept (its frame's size in memory, and its file's size)."""

MAX_RESULTS = 512
"""Result files kept in one OUT's cache folder (the oldest are removed past it)."""

_META = b"vge-result"
"""The schema metadata key holding the value's shape."""
_FRAMES = "frame"
"""The column of a result file: one row per frame of the value, as polars writes it."""


class _NotKept(Exception):
    """A value (or argument) of a kind this cache does not write."""


_RECORD_HOMES = ("vge_analytics.", "replay.")
"""The packages whose dataclasses a result may hold (a record's class is found by its name)."""


def _shape(value: Any, frames: list[pl.DataFrame]) -> Any:
    """`value` as JSON with its kinds tagged (a tuple stays a tuple, a dict keeps its order, a
    record of this code names its class and holds the fields it is made from); each frame is
    appended to `frames` and named by its place there."""
    if isinstance(value, pl.DataFrame):
        frames.append(value)
        return ["frame", len(frames) - 1]
    if value is None or isinstance(value, (bool, int, str)):
        return ["v", value]
    if isinstance(value, float):
        return ["float", value.hex()]  # every float, NaN and infinities too, bit for bit
    if isinstance(value, (tuple, list)):
        return ["tuple" if isinstance(value, tuple) else "list", [_shape(v, frames) for v in value]]
    if isinstance(value, dict) and all(isinstance(k, str) for k in value):
        return ["dict", [[k, _shape(v, frames)] for k, v in value.items()]]
    kind = type(value)
    if dataclasses.is_dataclass(value) and kind.__module__.startswith(_RECORD_HOMES):
        made = [f.name for f in dataclasses.fields(value) if f.init]
        fields = [[n, _shape(getattr(value, n), frames)] for n in made]
        return ["record", f"{kind.__module__}:{kind.__qualname__}", fields]
    raise _NotKept(kind.__name__)


def _record_class(name: str) -> type:
    """The dataclass `module:qualname` of this code (nothing else is looked up)."""
    module, _, qualname = name.partition(":")
    if not module.startswith(_RECORD_HOMES) or module not in sys.modules:
        raise _NotKept(name)
    found: Any = sys.modules[module]
    for part in qualname.split("."):
        found = getattr(found, part)
    if not (isinstance(found, type) and dataclasses.is_dataclass(found)):
        raise _NotKept(name)
    return found


def _value(shape: Any, frames: list[pl.DataFrame]) -> Any:
    """The value `_shape` described."""
    kind = shape[0]
    if kind == "frame":
        return frames[shape[1]]
    if kind == "v":
        return shape[1]
    if kind == "float":
        return float.fromhex(shape[1])
    if kind in ("tuple", "list"):
        items = [_value(s, frames) for s in shape[1]]
        return tuple(items) if kind == "tuple" else items
    if kind == "dict":
        return {k: _value(s, frames) for k, s in shape[1]}
    if kind == "record":
        return _record_class(shape[1])(**{k: _value(s, frames) for k, s in shape[2]})
    raise _NotKept(str(kind))


def _key(name: str, arguments: Any, version: str) -> str:
    doc = json.dumps([name, _shape(arguments, []), version, code_key()])
    return hashlib.sha256(doc.encode()).hexdigest()[:16]


def _read(path: Path) -> tuple[bool, Any]:
    """(True, the value kept at `path`) or (False, None) when there is none to read (absent, a
    link, too large, unreadable, or not a result)."""
    data = read_kept(path, MAX_RESULT_BYTES)
    if data is None:
        return False, None
    try:
        table = pa.ipc.open_file(pa.py_buffer(data)).read_all()
        shape = json.loads((table.schema.metadata or {})[_META])
        frames = [pl.read_ipc(io.BytesIO(b)) for b in table.column(_FRAMES).to_pylist()]
        return True, _value(shape, frames)
    except (OSError, KeyError, ValueError, TypeError, IndexError, AttributeError, _NotKept):
        return False, None
    except RecursionError:  # a shape nested deeper than any value: not one this code wrote
        return False, None
    except (pa.ArrowException, pl.exceptions.PolarsError):
        return False, None


def _write(path: Path, value: Any) -> bool:
    """Keep `value` at `path` (nothing when it is of another kind or too large): an Arrow IPC
    file of one row per frame (the frame as polars writes it), the shape in its metadata.
    Whether it was kept."""
    frames: list[pl.DataFrame] = []
    shape = _shape(value, frames)
    if sum(f.estimated_size() for f in frames) > MAX_RESULT_BYTES:
        return False
    parts = []
    for frame in frames:
        raw = io.BytesIO()
        frame.write_ipc(raw, compression="zstd")
        parts.append(raw.getvalue())
    table = pa.table({_FRAMES: pa.array(parts, pa.large_binary())})
    table = table.replace_schema_metadata({_META: json.dumps(shape).encode()})
    sink = pa.BufferOutputStream()
    with pa.ipc.new_file(sink, table.schema) as writer:
        writer.write_table(table)
    data = sink.getvalue().to_pybytes()
    if len(data) > MAX_RESULT_BYTES:
        return False
    path.parent.mkdir(exist_ok=True)
    with atomic_file(path, sync=False) as fh:
        fh.write(data)
    return True


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
        if _write(path, value):
            prune_kept(path, "result-*.arrow", MAX_RESULTS)
    return value


__all__ = ["MAX_RESULTS", "MAX_RESULT_BYTES", "kept_result"]
