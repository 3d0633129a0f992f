"""The output directory as a whole: the up-to-date check of a run (its inputs' sha256, the
options, the engine version), the files rebuilt from every run the manifest holds
(`quarantine.jsonl`, `runs/runs.parquet`, `manifest.json`), and the writer lock (`flock` on
the local disk, a lease in an object store: docs/SCALE.md)."""

from __future__ import annotations

import fcntl
import io
import os
import shutil
from collections import defaultdict
from collections.abc import Callable, Iterable
from typing import BinaryIO

import pyarrow.parquet as pq

from .._errors import ConfigError
from .._version import ENGINE_VERSION
from ..semantics import SCHEMA_VERSION
from ._durable import FileSet
from ._files import STATE_DIR
from ._fs import Location, confinement, location
from ._layout import (
    RUNS_TABLE,
    manifest_path,
    not_a_file_name,
    quarantine_path,
    run_json_path,
    runs_path,
    ssm_path,
    tasks_path,
)
from ._lease import Lease
from ._manifest import (
    FileRef,
    Hasher,
    ManifestFile,
    RunEntry,
    RunInputs,
    RunOptions,
    encode_manifest,
    runs_table,
    totals_of,
)
from ._reading import RunInput


def run_inputs(run: RunInput, bench_dir: str, hasher: Hasher, devices: Iterable[str]) -> RunInputs:
    """The inputs of a run and their sha256, an SSM for each device its tasks name (a device
    with no SSM yet too: one added later makes the run replay again). A device id that
    cannot name a file, or an SSM linked out of BENCH, is never made a path nor read."""
    bench = location(bench_dir)
    ssm: dict[str, FileRef] = {}
    known = hasher.ssm_refs  # the runs of a replay share their SSMs: each made once
    confined = None
    for d in sorted(devices):
        ref = known.get((bench_dir, d))
        if ref is None and not_a_file_name(d) is None:
            confined = confined or confinement(bench)
            path = ssm_path(bench, d)
            ref = hasher.ref(path) if confined(path) else FileRef(str(path), None)
            known[(bench_dir, d)] = ref
        if ref is not None:
            ssm[d] = ref
    return RunInputs(
        run_dir=run.run_dir,
        run_json=hasher.ref(run_json_path(location(run.run_dir))),
        episodes=hasher.ref(run.episodes),
        bench=bench_dir,
        tasks=hasher.ref(tasks_path(bench)),
        ssm=ssm,
    )


def up_to_date(
    prev: RunEntry,
    run: RunInput,
    bench_dir: str,
    options: RunOptions,
    hasher: Hasher,
    out: Location,
) -> RunInputs | None:
    """The run's current inputs if `prev` replayed exactly them (and its outputs exist)."""
    if prev.engine_version != ENGINE_VERSION or prev.options != options:
        return None
    now = run_inputs(run, bench_dir, hasher, prev.inputs.ssm)
    same = (
        now.run_json.sha256 == prev.inputs.run_json.sha256
        and now.episodes.sha256 == prev.inputs.episodes.sha256
        and now.tasks.sha256 == prev.inputs.tasks.sha256
        and all(now.ssm[d].sha256 == ref.sha256 for d, ref in prev.inputs.ssm.items())
    )
    if not same:
        return None
    outputs = prev.outputs
    expected = [*outputs.steps, *outputs.episodes, *outputs.goals]
    expected.append(f"{STATE_DIR}/quarantine/{prev.run_id}.jsonl")
    if not _all_present(out, expected):
        return None
    if outputs.mcap is not None and prev.counts.mcap_files and not (out / outputs.mcap).names():
        return None
    return now


def _all_present(out: Location, paths: list[str]) -> bool:
    """Whether every file exists: one listing per directory (not one request per file)."""
    by_dir: dict[str, set[str]] = defaultdict(set)
    for path in paths:
        parent, _, name = path.rpartition("/")
        by_dir[parent].add(name)
    return all(names <= set((out / d).names()) for d, names in sorted(by_dir.items()))


# ------------------------------------------------------------------------- publishing


class Publishing:
    """quarantine.jsonl, runs/runs.parquet and manifest.json, written whole but not yet in
    place: `commit` puts them there, the manifest (the commit marker) last."""

    def __init__(self, manifest: ManifestFile, commit: Callable[[], None]) -> None:
        self.manifest = manifest
        self.commit = commit


def prepare_publish(
    out: Location, entries: dict[str, RunEntry], staged: dict[str, Location] | None = None
) -> Publishing:
    """Make OUT's three files from the run entries (a run's quarantine records from
    `staged` if there, else from OUT's state), changing nothing in OUT: what fails here (a
    full disk, a meta the runs table cannot hold) leaves OUT as it was. On the local disk
    they are temporary files beside their places; elsewhere, bytes in memory."""
    runs = [entries[k] for k in sorted(entries)]
    qdir = out / STATE_DIR / "quarantine"
    present = set(qdir.names())
    staged = staged or {}

    def write_quarantine(fh: BinaryIO) -> None:
        for r in runs:
            name = f"{r.run_id}.jsonl"
            source = staged.get(r.run_id) or (qdir / name if name in present else None)
            if source is not None:
                with source.open_read() as src:
                    shutil.copyfileobj(src, fh)

    table = runs_table(runs)
    manifest = ManifestFile(
        engine_version=ENGINE_VERSION,
        schema_version=SCHEMA_VERSION,
        totals=totals_of(runs),
        runs=runs,
    )
    writers: list[tuple[Location, Callable[[BinaryIO], object]]] = [
        (quarantine_path(out), write_quarantine),
        (runs_path(out), lambda fh: pq.write_table(table, fh)),
        (manifest_path(out), lambda fh: fh.write(encode_manifest(manifest))),
    ]
    (out / RUNS_TABLE).mkdir()
    if out.local is None:  # uploaded whole, one after the other, when committed
        made = []
        for path, write in writers:
            buffer = io.BytesIO()
            write(buffer)
            made.append((path, buffer.getvalue()))

        def upload() -> None:
            for path, data in made:
                path.write_bytes(data)

        return Publishing(manifest, upload)
    files = FileSet()
    try:
        for path, write in writers:
            with files.file(path.local) as fh:  # type: ignore[arg-type]
                write(fh)
    except BaseException:
        files.discard()
        raise
    return Publishing(manifest, files.commit)


def publish(out: Location, entries: dict[str, RunEntry]) -> ManifestFile:
    """Rewrite quarantine.jsonl, runs/runs.parquet and manifest.json (last: the commit
    marker) from the run entries, all three or none."""
    publishing = prepare_publish(out, entries)
    publishing.commit()
    return publishing.manifest


class OutputLock:
    """One `vge replay` at a time per output directory: on the local disk a `flock` on
    `OUT/.replay/lock` (released if the process dies); in an object store a lease, the
    object `OUT/.replay/lock` (`_lease`), which `check` verifies before each commit."""

    def __init__(self, out: Location) -> None:
        state_dir = out / STATE_DIR
        state_dir.mkdir()
        self.path = None if state_dir.local is None else state_dir.local / "lock"
        self._fh: BinaryIO | None = None
        self._lease = None if out.local is not None else Lease(state_dir / "lock", str(out))

    def check(self) -> None:
        """Raise `ConfigError` (one line) if another writer took OUT (an object store's
        lease); the local lock cannot be taken while held."""
        if self._lease is not None:
            self._lease.check()

    def __enter__(self) -> OutputLock:
        if self._lease is not None:
            self._lease.take()
            return self
        if self.path is None:
            return self
        # never through a link left there (opening it "wb" would truncate its target)
        try:
            fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC, 0o666)
        except OSError as exc:
            raise ConfigError(f"{self.path}: cannot take the writer lock: {exc.strerror}") from None
        self._fh = os.fdopen(fd, "wb")
        try:
            fcntl.flock(self._fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            self._fh.close()
            raise ConfigError(
                f"{self.path.parent.parent}: another vge replay is writing to this directory"
            ) from None
        return self

    def __exit__(self, *exc: object) -> None:
        if self._lease is not None:
            self._lease.release()
        if self._fh is not None:
            fcntl.flock(self._fh, fcntl.LOCK_UN)
            self._fh.close()
            self._fh = None
