"""`OUT/manifest.json` and `OUT/runs/runs.parquet`: what was replayed, from what, with what.

The manifest holds, per run: the inputs (paths as given, sha256), the options, the engine
version, the counts (lines read = replayed + quarantined), quarantine kinds, a divergence
summary and the output files. No wall-clock time anywhere: the same inputs and options give
the same bytes. It is also the cache key of incremental replays and lets `vge sweep`
re-replay a run from its recorded run directory and benchmark.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any

import msgspec
import pyarrow as pa
from msgspec import Meta

from .._errors import InputError, decode_error_message
from ..semantics import py_column, run_lambda
from ._fs import Location, location
from ._layout import manifest_path
from ._lines import MAX_RECORD_BYTES

MANIFEST_FORMAT = "vge-replay-manifest"
MANIFEST_VERSION = 1


def _d(text: str) -> Meta:
    return Meta(description=text)


class FileRef(msgspec.Struct):
    """An input file: its path as given and its sha256 (null when the file is missing)."""

    path: str
    sha256: str | None


class RunInputs(msgspec.Struct, kw_only=True):
    run_dir: Annotated[str, _d("Run directory, as given")]
    run_json: FileRef
    episodes: FileRef
    bench: Annotated[str, _d("Benchmark directory, as given")]
    tasks: FileRef
    ssm: Annotated[dict[str, FileRef], _d("SSM of every device the run's episodes use")]


class RunOptions(msgspec.Struct, kw_only=True, omit_defaults=True):
    lam: Annotated[float | None, _d("--lambda, if given")] = msgspec.field(name="lambda")
    mcap: bool
    mcap_episodes: Annotated[list[str] | None, _d("Episodes with an MCAP file; null: all")]
    max_record_bytes: Annotated[
        int, _d("--max-record-bytes; absent when it is the default, 67108864 (64 MiB)")
    ] = MAX_RECORD_BYTES


class RunInfo(msgspec.Struct, kw_only=True):
    """From run.json."""

    model: str
    agent_kind: str
    lam: float | None = msgspec.field(name="lambda")
    meta: dict[str, Any]


class RunCounts(msgspec.Struct, kw_only=True):
    lines_read: Annotated[int, _d("Episode lines read (= replayed + quarantined)")]
    replayed: Annotated[int, _d("Episodes replayed")]
    quarantined: Annotated[int, _d("Records sent to quarantine.jsonl")]
    steps: Annotated[int, _d("Step rows (truncated ones included)")]
    truncated_steps: Annotated[int, _d("Steps logged after termination")]
    diverged_steps: Annotated[int, _d("Scored steps whose recorded values differ")]
    goals: Annotated[int, _d("Goal rows")]
    mcap_files: Annotated[int, _d("MCAP files written")]


class Divergence(msgspec.Struct, kw_only=True):
    steps_compared: Annotated[int, _d("Scored steps with a recorded feedback, state or view")]
    steps_diverged: Annotated[int, _d("Of those, steps where a recorded value differs")]
    episodes_diverged: Annotated[int, _d("Episodes with at least one diverged step")]
    by_field: Annotated[dict[str, int], _d("Diverged steps per field (feedback, state, view)")]


class RunOutputs(msgspec.Struct, kw_only=True):
    steps: list[str]
    episodes: list[str]
    goals: list[str]
    mcap: str | None


class RunEntry(msgspec.Struct, kw_only=True):
    """Everything about one replayed run."""

    run_id: str
    engine_version: str
    inputs: RunInputs
    options: RunOptions
    run: RunInfo
    counts: RunCounts
    quarantine: Annotated[dict[str, int], _d("Quarantined records by kind")]
    divergence: Divergence
    outputs: RunOutputs


class Totals(msgspec.Struct, kw_only=True):
    runs: int
    lines_read: int
    replayed: int
    quarantined: int
    steps: int
    truncated_steps: int
    diverged_steps: int


class ManifestFile(msgspec.Struct, kw_only=True):
    """The content of `OUT/manifest.json`."""

    format: str = MANIFEST_FORMAT
    manifest_version: int = MANIFEST_VERSION
    engine_version: str
    schema_version: int
    totals: Totals
    runs: list[RunEntry]


def totals_of(runs: list[RunEntry]) -> Totals:
    return Totals(
        runs=len(runs),
        lines_read=sum(r.counts.lines_read for r in runs),
        replayed=sum(r.counts.replayed for r in runs),
        quarantined=sum(r.counts.quarantined for r in runs),
        steps=sum(r.counts.steps for r in runs),
        truncated_steps=sum(r.counts.truncated_steps for r in runs),
        diverged_steps=sum(r.counts.diverged_steps for r in runs),
    )


_decoder = msgspec.json.Decoder(ManifestFile)
_encoder = msgspec.json.Encoder(order="deterministic")


def encode_manifest(manifest: ManifestFile) -> bytes:
    return msgspec.json.format(_encoder.encode(manifest), indent=2) + b"\n"


def read_manifest(out_dir: str | Path | Location) -> ManifestFile | None:
    """The manifest of an output directory (a path or a URI), or None if there is none yet."""
    path = manifest_path(location(out_dir))
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise InputError(str(path), f"cannot read: {exc.strerror or exc}") from None
    try:
        manifest = _decoder.decode(data)
    except msgspec.DecodeError as exc:
        raise InputError(
            str(path),
            f"not a replay manifest ({decode_error_message(exc)}); "
            "delete it (and the tables) or choose another --out",
        ) from None
    if manifest.format != MANIFEST_FORMAT:
        raise InputError(str(path), f"unknown manifest format {manifest.format!r}")
    return manifest


@dataclass
class Manifest:
    """What `replay_runs` returns: the manifest written, and what this call did."""

    path: Path | str
    """`OUT/manifest.json`: a path on the local disk, else its URI."""
    content: ManifestFile
    requested: list[str] = field(default_factory=list)
    replayed: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    nodes: dict[str, int] = field(default_factory=dict)
    """Batches replayed per cluster node (Ray only; never written to a file)."""

    def run(self, run_id: str) -> RunEntry:
        for entry in self.content.runs:
            if entry.run_id == run_id:
                return entry
        raise KeyError(run_id)

    @property
    def runs(self) -> list[RunEntry]:
        return self.content.runs

    @property
    def quarantined(self) -> int:
        """Records quarantined in the runs of this call (skipped runs included)."""
        return sum(self.run(r).counts.quarantined for r in self.requested)

    @property
    def exit_code(self) -> int:
        """0: everything replayed; 2: something was quarantined."""
        return 2 if self.quarantined else 0


# --------------------------------------------------------------------------- hashing


class Hasher:
    """sha256 of files, each computed once per call (None for a missing file); `ssm_refs`
    keeps the reference of each device's SSM, by (BENCH as given, device id), made once per
    call too (`_outdir.run_inputs`: every run of a benchmark names the same SSMs)."""

    def __init__(self) -> None:
        self._cache: dict[str, str | None] = {}
        self.ssm_refs: dict[tuple[str, str], FileRef] = {}

    def __call__(self, path: str | Path | Location) -> str | None:
        key = str(path)
        if key not in self._cache:
            self._cache[key] = _sha256(location(path))
        return self._cache[key]

    def ref(self, path: str | Path | Location) -> FileRef:
        return FileRef(str(path), self(path))


def _sha256(path: Location) -> str | None:
    h = hashlib.sha256()
    try:
        with path.open_read() as fh:
            while chunk := fh.read(1 << 20):
                h.update(chunk)
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise InputError(str(path), f"cannot read: {exc.strerror or exc}") from None
    return h.hexdigest()


# ------------------------------------------------------------------------ runs table

_RUN_COLUMNS = pa.schema(
    [
        pa.field("run_id", pa.string(), nullable=False),
        pa.field("model", pa.string(), nullable=False),
        pa.field("agent_kind", pa.string(), nullable=False),
        pa.field("lambda", pa.float64(), nullable=False),
        pa.field("lambda_run", pa.float64()),
        pa.field("lines_read", pa.int64(), nullable=False),
        pa.field("episodes", pa.int64(), nullable=False),
        pa.field("quarantined", pa.int64(), nullable=False),
        pa.field("steps", pa.int64(), nullable=False),
        pa.field("diverged_steps", pa.int64(), nullable=False),
        pa.field("complete", pa.bool_()),
        pa.field("infrastructure_failures", pa.int64()),
        pa.field("engine_version", pa.string(), nullable=False),
        pa.field("meta", pa.string(), nullable=False),
    ]
)
"""Fixed columns of `runs.parquet`; `meta_<key>` columns follow, sorted by key."""


def _is_scalar(value: Any) -> bool:
    return isinstance(value, (str, bool, int)) or (
        isinstance(value, float) and math.isfinite(value)
    )


def _meta_column(values: list[Any]) -> pa.Array:
    """One `meta_<key>` column: bool, int64, float64 or string (mixed types as JSON text)."""
    present = [v for v in values if v is not None]
    if all(isinstance(v, bool) for v in present):
        return py_column(values, pa.bool_())
    if all(isinstance(v, int) and not isinstance(v, bool) for v in present):
        return py_column(values, pa.int64())
    if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in present):
        return py_column([None if v is None else float(v) for v in values], pa.float64())
    return py_column(
        [v if v is None or isinstance(v, str) else msgspec.json.encode(v).decode() for v in values],
        pa.string(),
    )


def run_completeness(meta: dict[str, Any]) -> tuple[bool | None, int | None]:
    """(complete, infrastructure_failures) as run.json's meta says them (`vge run` writes
    both, PROTOCOL §10.2); None for a run that does not say (another harness, a synthetic
    run) or says it in another type."""
    complete = meta.get("complete")
    failures = meta.get("infrastructure_failures")
    return (
        complete if isinstance(complete, bool) else None,
        failures
        if isinstance(failures, int) and not isinstance(failures, bool) and 0 <= failures < 1 << 63
        else None,
    )


def runs_table(runs: list[RunEntry]) -> pa.Table:
    """One row per run: header, lambda, counts, meta as JSON and its scalars as columns."""
    fixed: dict[str, list[Any]] = {f.name: [] for f in _RUN_COLUMNS}
    for r in runs:
        fixed["run_id"].append(r.run_id)
        fixed["model"].append(r.run.model)
        fixed["agent_kind"].append(r.run.agent_kind)
        fixed["lambda"].append(run_lambda(r.run.lam, r.options.lam))
        fixed["lambda_run"].append(r.run.lam)
        fixed["lines_read"].append(r.counts.lines_read)
        fixed["episodes"].append(r.counts.replayed)
        fixed["quarantined"].append(r.counts.quarantined)
        fixed["steps"].append(r.counts.steps)
        fixed["diverged_steps"].append(r.counts.diverged_steps)
        complete, failures = run_completeness(r.run.meta)
        fixed["complete"].append(complete)
        fixed["infrastructure_failures"].append(failures)
        fixed["engine_version"].append(r.engine_version)
        fixed["meta"].append(_encoder.encode(r.run.meta).decode())
    arrays = [py_column(fixed[f.name], f.type) for f in _RUN_COLUMNS]  # no pandas
    fields = list(_RUN_COLUMNS)
    keys = sorted({k for r in runs for k, v in r.run.meta.items() if _is_scalar(v)})
    for key in keys:
        values = [r.run.meta.get(key) for r in runs]
        column = _meta_column([v if _is_scalar(v) else None for v in values])
        arrays.append(column)
        fields.append(pa.field(f"meta_{key}", column.type))
    return pa.Table.from_arrays(arrays, schema=pa.schema(fields))
