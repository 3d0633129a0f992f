"""The on-disk layout, in one place: the file and folder names of a benchmark (PROTOCOL §1.1),
of a run directory (§1.4, §10.3) and of a replay's output OUT (§7.1), the Parquet tables and
the grains a metric reads, and the paths built from them. Every path works on a local `Path`
and on a `Location` (a path or an object-store URI) alike."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, TypeVar

if TYPE_CHECKING:  # a type only: the layout imports no I/O (short import chains)
    from ._fs import Location

# ------------------------------------------------------------------ benchmark (§1.1)

SSM_DIR = "ssm"
"""`BENCH/ssm/<device_id>.json`: one state machine per device."""
UCSM_DIR = "ucsm"
"""`BENCH/ucsm/<Category>.json`: optional category templates."""
TASKS = "tasks.jsonl"
"""`BENCH/tasks.jsonl`: one episode definition per line."""
IMAGES_DIR = "images"
"""`BENCH/images/<device_id>/<view>.<ext>`: optional rendered views."""
IMAGE_EXTENSIONS = ("png", "jpg", "jpeg")
"""A view's picture file, in the order they are tried (§1.1)."""
SSM_SUFFIX = ".json"

# ------------------------------------------------------------------ run directory (§1.4)

RUN_JSON = "run.json"
EPISODES = "episodes.jsonl"
"""The episodes file a writer appends to (`vge synth` streams `episodes.jsonl.gz`)."""
EPISODES_GZ = EPISODES + ".gz"
EPISODES_FILES = (EPISODES, EPISODES_GZ)
"""The names a run's episodes file may have, in the order they are looked for."""
FAILURES = "failures.jsonl"
"""`RUN/failures.jsonl`: the episodes `vge run` lost to infrastructure failures (§10.3)."""

# ------------------------------------------------------------------ replay output (§7.1)

STEPS_TABLE = "steps"
EPISODES_TABLE = "episodes"
GOALS_TABLE = "goals"
RUNS_TABLE = "runs"
TABLES = (STEPS_TABLE, EPISODES_TABLE, GOALS_TABLE, RUNS_TABLE)
"""The tables of OUT, each a folder of Parquet files (`vge sql` reads them by these names)."""
PARTITIONED = (STEPS_TABLE, EPISODES_TABLE, GOALS_TABLE)
"""The tables written one folder per run (`OUT/<table>/run_id=<run_id>/`)."""
GRAINS = (EPISODES_TABLE, STEPS_TABLE, GOALS_TABLE)
"""The tables a metric may aggregate over (its grain, PROTOCOL §6), in the order they are
listed."""
PARTITION_KEY = "run_id"
"""A partition folder is `<PARTITION_KEY>=<run_id>` (Hive style, as DuckDB and Arrow read it)."""
RUNS_FILE = "runs.parquet"
"""`OUT/runs/runs.parquet`: one row per run."""
MCAP_DIR = "mcap"
"""`OUT/mcap/<run_id>/<episode>.mcap` (§7.8)."""
QUARANTINE = "quarantine.jsonl"
MANIFEST = "manifest.json"
METRIC_CACHE_DIR = ".metric-cache"
"""`OUT/.metric-cache/`: the metrics' per-run terms, the tables' schemas and the dashboard's
kept results, kept by the analytics (PROTOCOL §7.1; docs/METRICS.md); never read by the
replay, safe to delete."""

_P = TypeVar("_P", Path, "Location")


def not_a_file_name(name: str) -> str | None:
    """Why an id (a device, a view) cannot be one file or folder name inside BENCH (PROTOCOL
    §1.5), or None when it can: it would leave its folder or fail to open."""
    if name in ("", ".", ".."):
        return "is not a name"
    if any(c in name for c in "/\\\0"):
        return "holds '/', '\\' or a NUL byte"
    return None


def relative_inside(ref: str) -> bool:
    """Whether a path an SSM names (`images`) stays inside BENCH as written: relative, no
    `..`, no NUL byte (PROTOCOL §1.1). Links are judged where the file is read."""
    parts = ref.replace("\\", "/").split("/")
    return bool(ref) and "\0" not in ref and not ref.startswith("/") and ".." not in parts


def ssm_path(bench: _P, device_id: str) -> _P:
    """`BENCH/ssm/<device_id>.json`."""
    return bench / SSM_DIR / f"{device_id}{SSM_SUFFIX}"


def image_path(bench: _P, device_id: str, view: str, ext: str = IMAGE_EXTENSIONS[0]) -> _P:
    """`BENCH/images/<device_id>/<view>.<ext>`."""
    return bench / IMAGES_DIR / device_id / f"{view}.{ext}"


def image_paths(bench: _P, device_id: str, view: str) -> list[_P]:
    """`BENCH/images/<device_id>/<view>.png`, `.jpg`, `.jpeg`: where a view's picture file may
    be, in the order they are tried (§1.1)."""
    return [image_path(bench, device_id, view, ext) for ext in IMAGE_EXTENSIONS]


def tasks_path(bench: _P) -> _P:
    return bench / TASKS


def run_json_path(run_dir: _P) -> _P:
    return run_dir / RUN_JSON


def partition(run_id: str) -> str:
    """The folder of one run in a partitioned table: `run_id=<run_id>`."""
    return f"{PARTITION_KEY}={run_id}"


def partition_dir(out: _P, table: str, run_id: str) -> _P:
    """`OUT/<table>/run_id=<run_id>`."""
    return out / table / partition(run_id)


def listed_part(table: str, run_id: str, file: str) -> str:
    """`<table>/run_id=<run_id>/<file>`: a Parquet part as the manifest lists it."""
    return f"{table}/{partition(run_id)}/{file}"


def metric_cache_path(out: _P, grain: str, manifest_key: str, definitions_key: str) -> _P:
    """`OUT/.metric-cache/<grain>-<manifest_key>-<definitions_key>.parquet`: the per-episode
    terms of the metrics of one grain, for one manifest and one set of definitions."""
    return out / METRIC_CACHE_DIR / f"{grain}-{manifest_key}-{definitions_key}.parquet"


def episode_terms_path(out: _P, grain: str, contents_key: str, definitions_key: str) -> _P:
    """`OUT/.metric-cache/terms_<grain>-<contents_key>-<definitions_key>.parquet`: the terms
    of the metrics of one grain per (run, episode), with the episodes' cluster columns, for
    one content of OUT and one set of definitions."""
    return out / METRIC_CACHE_DIR / f"terms_{grain}-{contents_key}-{definitions_key}.parquet"


def step_counts_path(out: _P, part: str, contents_key: str, query_key: str) -> _P:
    """`OUT/.metric-cache/counts_<part>-<contents_key>-<query_key>.parquet`: the scored steps
    counted per run, category and the columns of `part` (error type; switch class; device
    and view), for one content of OUT and one version of the query counting them."""
    return out / METRIC_CACHE_DIR / f"counts_{part}-{contents_key}-{query_key}.parquet"


def schema_cache_path(out: _P, table: str, contents_key: str) -> _P:
    """`OUT/.metric-cache/schema-<table>-<contents_key>.arrow`: a table's schema as its files
    unify it, kept for one content of OUT."""
    return out / METRIC_CACHE_DIR / f"schema-{table}-{contents_key}.arrow"


def answer_cache_path(out: _P, contents_key: str, question_key: str) -> _P:
    """`OUT/.metric-cache/answer-<contents_key>-<question_key>.json`: what a command printed
    for one question (its options, the metrics' definitions, the code), kept for one content
    of OUT."""
    return out / METRIC_CACHE_DIR / f"answer-{contents_key}-{question_key}.json"


def result_cache_path(out: _P, contents_key: str, result_key: str) -> _P:
    """`OUT/.metric-cache/result-<contents_key>-<result_key>.arrow`: one result the dashboard
    computed from OUT (a function of its tables and its arguments), kept for one content."""
    return out / METRIC_CACHE_DIR / f"result-{contents_key}-{result_key}.arrow"


def runs_path(out: _P) -> _P:
    """`OUT/runs/runs.parquet`."""
    return out / RUNS_TABLE / RUNS_FILE


def mcap_dir(out: _P, run_id: str) -> _P:
    """`OUT/mcap/<run_id>`: the MCAP files of one run."""
    return out / MCAP_DIR / run_id


def listed_mcap(run_id: str) -> str:
    """`mcap/<run_id>`: the MCAP folder of a run as the manifest lists it."""
    return f"{MCAP_DIR}/{run_id}"


def manifest_path(out: _P) -> _P:
    return out / MANIFEST


def quarantine_path(out: _P) -> _P:
    return out / QUARANTINE

