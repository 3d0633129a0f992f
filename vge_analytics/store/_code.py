"""The key of the code that computes what is kept beside OUT (the dashboard's results,
`_results`; the answers `vge metrics` printed, `commands._answers`): another version of the
code computes afresh. Light to import: the answers' warm path asks for it before anything
heavy is imported."""

from __future__ import annotations

import hashlib
import importlib.util
import os
import sys
from functools import cache
from pathlib import Path

SOURCES = (".py", ".sql", ".pyx", ".pxd")
"""The files of `replay` and `vge_analytics` whose text is the code (the compiled kernel follows
from its `.pyx`)."""

LIBRARIES = ("click", "typer", "rich", "polars", "pyarrow", "duckdb", "msgspec")
"""The libraries whose code computes or prints a kept value, beside the package's own: each is
told by the size and modification time of its first module (found, not imported)."""


@cache
def code_key() -> str:
    """A hash of Python's version, the text of every source file of `replay` and
    `vge_analytics` (an editable install changes them without a new version), and
    `LIBRARIES`' first modules."""
    h = hashlib.sha256(sys.version.encode())
    for package in ("replay", "vge_analytics"):
        root = Path(__file__).resolve().parents[2] / package
        for path in sorted(root.rglob("*")):
            if path.suffix in SOURCES and "__pycache__" not in path.parts and path.is_file():
                h.update(f"\0{path.relative_to(root).as_posix()}\0".encode())
                h.update(path.read_bytes())
    for name in LIBRARIES:
        spec = importlib.util.find_spec(name)
        origin = spec.origin if spec is not None else None
        st = os.stat(origin) if origin and os.path.exists(origin) else None
        h.update(f"\0{name}\0{origin}\0{st and st.st_size}\0{st and st.st_mtime_ns}".encode())
    return h.hexdigest()[:16]


__all__ = ["LIBRARIES", "SOURCES", "code_key"]
