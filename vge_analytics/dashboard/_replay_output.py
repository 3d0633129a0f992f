"""OUT: where it is, whether it is usable, its version, summary and facets."""


from __future__ import annotations

import hashlib
import threading
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import replay
from replay.io import EPISODES_TABLE, MANIFEST, RUNS_TABLE, TABLES, manifest_path

from .. import store
from .._errors import OutputDirError
from ._where import DEFAULT_OUT

if TYPE_CHECKING:
    import polars as pl



def check_out(out: str | Path) -> Path:
    """OUT, resolved, if it is a replay output directory; else an error saying what to run."""
    shown = str(out)
    if replay.is_uri(shown):
        if not shown.startswith("file://"):  # opening it would reach the store: say so first
            raise OutputDirError(
                f"{shown}: the dashboard reads OUT on this machine (its viewer opens the "
                "episodes' files); copy OUT down first, or query it where it is with vge "
                "metrics, errors, compare, rescore, sweep and sql"
            )
        path = replay.location(shown).local
        assert path is not None  # a file:// URI names a local path
    else:
        path = Path(shown).expanduser()
    if not path.is_dir():
        hint = (
            "run `vge demo` first (it replays the bundled sample into ./logs-replayed)"
            if path.name == DEFAULT_OUT
            else f"run `vge demo`, or `vge replay RUN... --bench BENCH --out {shown}`, first"
        )
        raise OutputDirError(f"No replay output at {shown}: {hint}")
    missing = [t for t in TABLES if not (path / t).is_dir()]
    if missing or not manifest_path(path).is_file():
        what = ", ".join(f"{m}/" for m in missing) or MANIFEST
        raise OutputDirError(
            f"{shown} is not a replay output directory (no {what}): run `vge replay RUN... "
            f"--bench BENCH --out {shown}` first"
        )
    return path.resolve()


RACY_SECONDS = 2.0
"""A manifest modified this recently is hashed again on every call: a rewrite within the
file system's timestamp tick (up to 2 s on some) could leave its stat unchanged."""

_VERSIONS: dict[str, tuple[tuple[int, ...], str]] = {}
_VERSIONS_LOCK = threading.Lock()


def out_version(out: str | Path) -> str:
    """Content hash of OUT/manifest.json: the cache key of everything computed from OUT.

    A replay rewrites the manifest (input hashes, counts, engine version), so any change of
    the tables changes this value. Every page's cached result asks for it, and the manifest
    of a large OUT is big (156 MB at 100 times the full benchmark, 0.3 s to read and hash), so
    the hash is kept per path while the file's inode, size, modification and change times
    stay the same (and it is not younger than `RACY_SECONDS`).
    """
    path = manifest_path(Path(out))
    try:
        st = path.stat()
    except OSError:
        return hashlib.sha256(b"").hexdigest()[:16]
    stamp = (st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns)
    key = str(path)
    with _VERSIONS_LOCK:
        hit = _VERSIONS.get(key)
    if hit is not None and hit[0] == stamp:
        return hit[1]
    try:
        data = path.read_bytes()
    except OSError:
        data = b""
    version = hashlib.sha256(data).hexdigest()[:16]
    if time.time_ns() - st.st_mtime_ns > RACY_SECONDS * 1e9:
        with _VERSIONS_LOCK:
            _VERSIONS[key] = (stamp, version)
    return version


@dataclass(frozen=True)
class OutSummary:
    """What the sidebar says about OUT."""

    out: str
    engine_version: str
    runs: int
    episodes: int
    steps: int
    quarantined: int
    benches: tuple[str, ...]


def out_summary(out: str | Path) -> OutSummary:
    """Counts and provenance of OUT from its manifest."""
    manifest = store.open_store(out).manifest
    totals = manifest.get("totals") or {}
    benches = sorted({r["inputs"]["bench"] for r in manifest.get("runs", []) if "inputs" in r})
    return OutSummary(
        out=str(out),
        engine_version=str(manifest.get("engine_version", "?")),
        runs=int(totals.get("runs", len(manifest.get("runs", [])))),
        episodes=int(totals.get("replayed", 0)),
        steps=int(totals.get("steps", 0)),
        quarantined=int(totals.get("quarantined", 0)),
        benches=tuple(benches),
    )


def column_values(out: str | Path, table: str, column: str) -> list:
    """Distinct non-null values of a scalar column of runs/episodes, sorted."""
    opened = store.open_store(out)
    if table not in (RUNS_TABLE, EPISODES_TABLE):
        raise OutputDirError(f"no value list for table {table!r}")
    store.check_columns(opened, [column], [table], "filter")
    col = store.quote_ident(column)
    sql = f"SELECT DISTINCT {col} AS v FROM {table} WHERE {col} IS NOT NULL ORDER BY 1"
    return store.run_query(opened, sql, [])["v"].to_list()


def runs_matching(runs: pl.DataFrame, filters: Mapping[str, Sequence[object]]) -> list[str]:
    """Run ids of a `runs` table whose columns take one of the filter values (run columns
    only; a filter on another column is ignored here)."""
    import polars as pl

    mask = pl.lit(True)
    for column, values in filters.items():
        if column in runs.columns and values:
            wanted = list(values)
            cond = pl.col(column).is_in([v for v in wanted if v is not None])
            if any(v is None for v in wanted):
                cond = cond | pl.col(column).is_null()
            mask = mask & cond
    return runs.filter(mask)["run_id"].to_list()
