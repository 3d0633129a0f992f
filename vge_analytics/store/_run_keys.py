"""The key of each run's steps files, and the counts kept for an earlier content of OUT: what
lets the step counts (`_step_counts`) count again only the runs that changed.

A run's rows in the step counts are made of the files the dataset gives that run (the
manifest's run that lists each file, the fragment's partition: whatever run_id a file holds,
or the folder it sits in) and of nothing else. So a run's key is a hash of each such file's
path relative to OUT, size and modification time (as `_kept.contents_key` hashes every
file for the whole), and of the types the store gives the counted columns (the files'
schemas as they unify): a file replayed again or changed by hand, moved, added or taken from
the run, or another type, gives another key. The keys are looked at before the count reads a
file: a file changed while it is read is counted again next time.

The keys are kept in the footer of the counts' file (`RUN_KEYS`, JSON: run -> key); a file
kept for another content of OUT is found by its name (`counts_<part>-<contents>-<query>`,
the same query's, the newest), read within the part's byte bound as any kept file (no link,
no FIFO), and used only when its columns are the part's, its runs all have keys and none
is null.
"""

from __future__ import annotations

import hashlib
import os
import re
from collections.abc import Sequence
from pathlib import Path

import msgspec
import polars as pl

from replay.io import PARTITION_KEY, STEPS_TABLE

from ._datasets import run_files
from ._kept import read_kept_footed
from ._store import Store

RUN_KEYS = "vge.run_keys"
"""The name the counts' file keeps its runs' keys under, in its footer."""


def run_keys(store: Store, columns: Sequence[str]) -> dict[str, str] | None:
    """run -> the key of its steps files and of the types of `columns` (sorted by run), or
    None where they cannot be had: the steps table not files on the local disk, a file that
    cannot be looked at or outside OUT's folder, or one of no run."""
    listed = run_files(store.sources.get(STEPS_TABLE))
    if listed is None:
        return None
    types = store.columns[STEPS_TABLE]
    salt = msgspec.json.encode([[c, types.get(c)] for c in columns])
    base = f"{str(store.out).rstrip('/')}/"
    files: dict[str, list[str]] = {}
    for run, paths in listed.items():
        for path in paths:
            if not path.startswith(base):
                return None
            try:
                st = os.stat(path)
            except OSError:
                return None
            entry = f"{path[len(base) :]}\0{st.st_size}\0{st.st_mtime_ns}"
            files.setdefault(run, []).append(entry)
    return {run: _key(salt, entries) for run, entries in sorted(files.items())}


def _key(salt: bytes, entries: list[str]) -> str:
    h = hashlib.sha256(salt)
    for entry in sorted(entries):
        h.update(b"\0\0" + entry.encode("utf-8", "surrogateescape"))
    return h.hexdigest()[:16]


def earlier(path: Path, limit: int) -> tuple[pl.DataFrame, dict[str, str]] | None:
    """The counts kept beside `path` for another content of OUT (the newest of the same part
    and query) and its runs' keys, read within `limit` bytes, or None: none kept, not one of
    ours (not Parquet, a link, no keys in its footer, a run's rows without a key, a null
    run). Its columns are the caller's to check."""
    part, query = path.stem.split("-")[0], path.stem.rsplit("-", 1)[1]
    named = re.compile(rf"{re.escape(part)}-[0-9a-f]{{16}}-{re.escape(query)}\.parquet")
    found = []
    try:
        for entry in os.scandir(path.parent):
            if entry.name != path.name and named.fullmatch(entry.name):
                found.append((entry.stat(follow_symlinks=False).st_mtime_ns, entry.name))
    except OSError:
        return None
    if not found:
        return None
    kept = read_kept_footed(path.parent / max(found)[1], limit, RUN_KEYS)
    if kept is None:
        return None
    frame, footer = kept
    try:
        keys = msgspec.json.decode(footer, type=dict[str, str])
    except msgspec.MsgspecError:
        return None
    runs = frame.get_column(PARTITION_KEY, default=None)
    if runs is None or runs.dtype != pl.String or runs.null_count():
        return None
    if not set(runs.unique().to_list()) <= keys.keys():
        return None
    return frame, keys


__all__ = ["RUN_KEYS", "earlier", "run_keys"]
