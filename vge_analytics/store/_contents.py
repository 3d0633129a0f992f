"""What a local OUT holds, read without opening it: its manifest as a store reads it, the
files of each table, and the key of its contents (`_kept.contents_key`). Light to import
(no pyarrow, no DuckDB): `vge metrics OUT` looks for its kept answer with it before anything
heavy is imported (docs/METRICS.md, The metric cache).
"""

from __future__ import annotations

import contextlib
import gc
import hashlib
import json
import os
from collections.abc import Iterator, Mapping
from pathlib import Path, PurePosixPath

import msgspec

import replay
from replay.io import RUNS_TABLE, TABLES, manifest_path

from .._errors import OutputDirError
from ._kept import contents_key


def read_manifest(out: Path | replay.Location) -> dict | None:
    """OUT's manifest; None when it has none."""
    path = manifest_path(out)
    if not path.exists():
        return None
    try:
        data = json.loads(path.read_bytes().decode("utf-8"))
    except (OSError, ValueError) as exc:
        raise OutputDirError(f"{path}: unreadable manifest ({exc})") from None
    return data if isinstance(data, dict) else {}


class _Inputs(msgspec.Struct):
    bench: object = msgspec.UNSET


class _Run(msgspec.Struct):
    run_id: object = None
    outputs: object = None
    inputs: _Inputs | msgspec.UnsetType = msgspec.UNSET


class _Manifest(msgspec.Struct):
    """What a store reads of a manifest: each run's id, files and benchmark, the totals and
    the engine version (the inputs' digests, most of a large manifest, are skipped)."""

    runs: list[_Run] = []
    totals: object = msgspec.UNSET
    engine_version: object = msgspec.UNSET


def _store_manifest(raw: bytes) -> dict | None:
    """The parts of a manifest a store reads (`_Manifest`) as the dict `json` would give,
    or None when it does not have that shape (then it is read whole, and checked)."""
    try:
        doc = msgspec.json.decode(raw, type=_Manifest)
    except msgspec.MsgspecError:
        return None
    runs = []
    for run in doc.runs:
        entry = {"run_id": run.run_id, "outputs": run.outputs}
        if run.inputs is not msgspec.UNSET and run.inputs.bench is not msgspec.UNSET:
            entry["inputs"] = {"bench": run.inputs.bench}
        runs.append(entry)
    fields = {"totals": doc.totals, "engine_version": doc.engine_version}
    return {**{k: v for k, v in fields.items() if v is not msgspec.UNSET}, "runs": runs}


def manifest_and_digest(out: Path | replay.Location) -> tuple[dict | None, str | None]:
    """What a store reads of OUT's manifest (`_store_manifest`) and the sha256 of its
    bytes; (None, None) when it has none."""
    path = manifest_path(out)
    if not path.exists():
        return None, None
    try:
        raw = path.read_bytes()
        data = _store_manifest(raw)
        if data is None:
            data = json.loads(raw.decode("utf-8"))
    except (OSError, ValueError) as exc:
        raise OutputDirError(f"{path}: unreadable manifest ({exc})") from None
    return (data if isinstance(data, dict) else {}), hashlib.sha256(raw).hexdigest()


@contextlib.contextmanager
def no_collection() -> Iterator[None]:
    """The garbage collector paused: a manifest of many runs is millions of objects, which
    the collector would otherwise walk again and again while they are made (none is a
    cycle)."""
    was = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was:
            gc.enable()


def _refuse(out: replay.Location, what: str) -> OutputDirError:
    return OutputDirError(f"{manifest_path(out)}: {what}")


def _real(path: str, folders: dict[str, str], *, keep: bool = False) -> str:
    """`os.path.realpath(path)`, built from its folder's, each folder resolved once
    (`folders` keeps them, `keep`): a path that is no link is its resolved folder's entry."""
    hit = folders.get(path)
    if hit is not None:
        return hit
    folder, _, entry = path.rpartition("/")
    if not folder or os.path.islink(path):
        real = os.path.realpath(path)
    else:
        real = f"{_real(folder, folders, keep=True).rstrip('/')}/{entry}"
    if keep:
        folders[path] = real
    return real


def _checked(
    out: replay.Location, table: str, name: object, who: str, folders: dict[str, str]
) -> str:
    """`name` if it is the path of a file of `table` inside OUT, else the error; `who`: what
    listed it, as the message says it (`OUT/manifest.json: run 'x' lists`); `folders`: the
    folders resolved so far (`_real`; OUT's own under "")."""
    if not isinstance(name, str):
        raise OutputDirError(f"{who} {name!r} as a {table} file (not a path)")
    parts = PurePosixPath(name).parts
    if name.startswith("/") or ".." in parts or parts[:1] != (table,):
        raise OutputDirError(f"{who} {name!r}, which is not a file of {table}/ in OUT")
    if out.local is not None:
        if "" not in folders:
            folders[""] = os.path.realpath(out.local)
        inside = folders[""]
        real = os.path.normpath(_real(os.path.join(out.local, name), folders))
        if os.path.commonpath([inside, real]) != inside:
            raise OutputDirError(f"{who} {name!r}, which leads outside OUT ({real})")
    return name


def _listed(out: replay.Location, manifest: Mapping, table: str) -> list[tuple[str, str | None]]:
    """(path, run) of each file of `table` the manifest lists, checked."""
    runs = manifest.get("runs", [])
    if not isinstance(runs, list):
        raise _refuse(out, "'runs' is not a list")
    found: list[tuple[str, str | None]] = []
    folders: dict[str, str] = {}
    for run in runs:
        run_id = run.get("run_id") if isinstance(run, dict) else None
        outputs = run.get("outputs") if isinstance(run, dict) else None
        names = outputs.get(table) if isinstance(outputs, dict) else None
        if not isinstance(run_id, str) or not isinstance(names, list):
            raise _refuse(out, f"a run without a run_id and its {table} files ({str(run)[:80]})")
        who = f"{manifest_path(out)}: run {run_id!r} lists"
        found += [(_checked(out, table, name, who, folders), run_id) for name in names]
    return sorted(found)


def table_files(
    out: replay.Location, manifest: Mapping | None, table: str
) -> list[tuple[str, str | None]]:
    """(path relative to OUT, the run whose rows it holds, or None) of each file of a table."""
    if table == RUNS_TABLE:
        names = [f"{RUNS_TABLE}/{n}" for n in (out / RUNS_TABLE).names() if n.endswith(".parquet")]
    elif manifest is None:  # a local OUT without a manifest: its folders, file by file
        names = [f"{table}/{rel}" for rel in (out / table).files() if rel.endswith(".parquet")]
    else:
        return _listed(out, manifest, table)
    folders: dict[str, str] = {}
    who = f"{out}: OUT holds"
    return [(_checked(out, table, name, who, folders), None) for name in names]


def local_contents(out: Path) -> str | None:
    """The key of a local OUT's contents, as a store opened on it has it (`Store.contents`),
    or None (no manifest, a file listed outside OUT or missing, an unreadable manifest)."""
    out = out.resolve()  # as `open_store` has it
    try:
        with no_collection():
            manifest, digest = manifest_and_digest(out)
            if manifest is None:
                return None
            where = replay.location(out)
            files = {table: table_files(where, manifest, table) for table in TABLES}
    except (OSError, OutputDirError):
        return None
    return contents_key(where, files, digest)


__all__ = [
    "local_contents",
    "manifest_and_digest",
    "no_collection",
    "read_manifest",
    "table_files",
]
