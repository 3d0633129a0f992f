"""The default memory limit of a command's queries, sized from the OUT they read.

A quarter of the machine's memory (what the Python API takes by default) is far more than the
queries over a small OUT need, and it is also what one hostile metric file may take before its
query is stopped (`repeat(episode_id, 20000000)`: DuckDB does not account for that value, the
process cap does). So the commands (`vge metrics`, `compare`, `sql`, `app`, ...) size the
default from OUT: 512 MB plus half the bytes of its tables, at most that quarter. On the
bundled sample that is 513 MB (a hostile query stops under 1.5 GB for the whole process); on
100x the full benchmark (8.3 GB of tables, 900 runs) it is the quarter, which reading its
Parquet footers needs (768 MB was measured too little there).
"""

from __future__ import annotations

import contextlib
import os

from replay.io import PARTITIONED, RUNS_TABLE

from ._limits import default_memory_limit

BASE_MEMORY = 512 * 1024**2
"""The sized default's floor: what the built-in queries over a small OUT take, with room."""
DATA_SHARE = 0.5
"""The sized default grows by this share of the bytes of OUT's tables."""


def _local_bytes(root: str) -> int:
    """Bytes of the regular files under `root`, links not followed (`root` included)."""
    if os.path.islink(root):
        return 0
    total = 0
    stack = [root]
    while stack:
        with contextlib.suppress(OSError), os.scandir(stack.pop()) as entries:
            for entry in entries:
                if entry.is_dir(follow_symlinks=False):
                    stack.append(entry.path)
                elif entry.is_file(follow_symlinks=False):
                    total += entry.stat(follow_symlinks=False).st_size
    return total


def table_bytes(out: str | os.PathLike[str] | None) -> int | None:
    """Bytes of OUT's tables (its Parquet folders), local or in object storage; None when
    they cannot be listed, or there is no OUT (the caller falls back to the machine's
    share)."""
    from replay.io import is_uri, location  # pyarrow's filesystems: not at import

    if out is None:
        return None
    text = os.fspath(out)
    names = (*PARTITIONED, RUNS_TABLE)
    if not is_uri(text):
        return sum(_local_bytes(os.path.join(text, name)) for name in names)
    try:
        import pyarrow.fs as pafs

        loc = location(text)
        if loc.local is not None:
            return sum(_local_bytes(str(loc.local / name)) for name in names)
        total = 0
        for name in names:
            selector = pafs.FileSelector((loc / name).path, allow_not_found=True, recursive=True)
            total += sum(info.size or 0 for info in loc.fs.get_file_info(selector))
        return total
    except Exception:  # noqa: BLE001 - any failure to list: the unsized default
        return None


def sized_memory_limit(out: str | os.PathLike[str] | None, given: str | int | None) -> str | int:
    """The memory limit of a command's queries over OUT: `given` (`--memory-limit`), else
    512 MB plus half the bytes of OUT's tables, at most a quarter of the machine's memory."""
    if given is not None:
        return given
    quarter = default_memory_limit()
    size = table_bytes(out)
    if size is None:
        return quarter
    return min(quarter, BASE_MEMORY + int(size * DATA_SHARE))


__all__ = ["BASE_MEMORY", "DATA_SHARE", "sized_memory_limit", "table_bytes"]
