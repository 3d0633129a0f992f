"""Input and output: loading benchmarks and logs, batches, Parquet parts, manifest, quarantine,
MCAP, the runner, and the one run-directory writer with its crash-safe file primitives.

The way through `vge replay` (`replay_runs`): the runner (`_runner`) gives each run a job
(`_job`), a job cuts its episodes file into batches (`_batch`), `replay_batch` replays one
and writes its parts, here, in worker processes (`_executor`, `_worker`) or on Ray (`_ray`).

Public here: what `replay` exports from this layer (the runner, the readers, the images, the
MCAP writer, the manifest) and what the tools built on the engine need beside it: the
run-directory writer of `vge run`, `vge play` and `vge synth`, the executors and batch
function of `vge sweep`, file names made from ids, the JSON Schemas, and for the benchmarks
the episode decoder, a process's worker state and the reference's tables of a batch. The
on-disk layout (file, folder and table names, and the paths built from them, `_layout`) is
public here for every reader of a benchmark, a run or OUT.
"""

from typing import TYPE_CHECKING

from .._lazy import lazy_names

if TYPE_CHECKING:  # the names, imported when first used (`lazy_names`)
    from ._batch import reference_tables, replay_batch
    from ._durable import (
        append_record,
        atomic_file,
        fsync_dir,
        make_folders,
        staged_path,
        truncate,
        write_all,
        write_atomic,
    )
    from ._executor import Executor, in_order, make_executor, start_method
    from ._file_names import mcap_file_name, safe_file_name
    from ._files import ROW_GROUP_ROWS, write_part
    from ._fs import Location, is_uri, location
    from ._images import (
        MAX_IMAGE_BYTES,
        MAX_IMAGE_PIXELS,
        BenchImages,
        ImageSource,
        ViewImage,
        as_view_image,
        bench_image,
        bench_image_problem,
        decode_picture,
        decode_view_image,
        open_picture,
        view_image_of,
    )
    from ._lambdas import LambdaBatch, LambdaTask, replay_lambdas
    from ._layout import (
        EPISODES,
        EPISODES_FILES,
        EPISODES_GZ,
        EPISODES_TABLE,
        FAILURES,
        GOALS_TABLE,
        GRAINS,
        IMAGE_EXTENSIONS,
        IMAGES_DIR,
        MANIFEST,
        MCAP_DIR,
        METRIC_CACHE_DIR,
        PARTITION_KEY,
        PARTITIONED,
        QUARANTINE,
        RUN_JSON,
        RUNS_FILE,
        RUNS_TABLE,
        SSM_DIR,
        SSM_SUFFIX,
        STEPS_TABLE,
        TABLES,
        TASKS,
        UCSM_DIR,
        answer_cache_path,
        episode_terms_path,
        image_path,
        image_paths,
        listed_mcap,
        listed_part,
        manifest_path,
        mcap_dir,
        metric_cache_path,
        partition,
        partition_dir,
        quarantine_path,
        result_cache_path,
        run_json_path,
        runs_path,
        schema_cache_path,
        ssm_path,
        step_counts_path,
        tasks_path,
    )
    from ._lines import MAX_RECORD_BYTES, iter_lines
    from ._load import (
        Benchmark,
        decode_episode_line,
        decode_state_machine,
        episode_decoder,
        episodes_file,
        load_machine,
        load_ssm,
        picture_problems,
        read_run_header,
        run_header_bytes,
        validate_benchmark,
        validate_run,
    )
    from ._manifest import Manifest, ManifestFile, RunEntry, read_manifest, runs_table
    from ._mcap import (
        MCAP_LIBRARY,
        attached_ssm,
        episode_mcap_path,
        write_episode_mcap,
    )
    from ._quarantine import QUARANTINE_KINDS, QuarantineRecord
    from ._record_schema import record_schema
    from ._rows import TABLE_ROWS
    from ._rundir import RunDirectory, keep_aside
    from ._runner import replay_runs
    from ._schemas import schema_documents, write_schemas
    from ._worker import Ready, worker_state

__all__ = [
    # the runner and its output
    "QUARANTINE_KINDS",
    "Manifest",
    "ManifestFile",
    "QuarantineRecord",
    "RunEntry",
    "read_manifest",
    "replay_runs",
    "runs_table",
    "ROW_GROUP_ROWS",
    "write_part",
    # inputs
    "MAX_RECORD_BYTES",
    "Benchmark",
    "Location",
    "decode_episode_line",
    "decode_state_machine",
    "episode_decoder",
    "episodes_file",
    "is_uri",
    "iter_lines",
    "load_machine",
    "load_ssm",
    "location",
    "picture_problems",
    "read_run_header",
    "validate_benchmark",
    "validate_run",
    # pictures and MCAP
    "MAX_IMAGE_BYTES",
    "MAX_IMAGE_PIXELS",
    "MCAP_LIBRARY",
    "BenchImages",
    "ImageSource",
    "ViewImage",
    "as_view_image",
    "attached_ssm",
    "bench_image",
    "bench_image_problem",
    "decode_picture",
    "decode_view_image",
    "open_picture",
    "view_image_of",
    "episode_mcap_path",
    "mcap_file_name",
    "write_episode_mcap",
    # writing run directories
    "EPISODES",
    "EPISODES_FILES",
    "EPISODES_GZ",
    "EPISODES_TABLE",
    "FAILURES",
    "GOALS_TABLE",
    "GRAINS",
    "IMAGES_DIR",
    "IMAGE_EXTENSIONS",
    "MANIFEST",
    "MCAP_DIR",
    "METRIC_CACHE_DIR",
    "PARTITIONED",
    "PARTITION_KEY",
    "QUARANTINE",
    "RUNS_FILE",
    "RUNS_TABLE",
    "RUN_JSON",
    "SSM_DIR",
    "SSM_SUFFIX",
    "STEPS_TABLE",
    "TABLES",
    "TABLE_ROWS",
    "TASKS",
    "UCSM_DIR",
    "RunDirectory",
    "append_record",
    "atomic_file",
    "fsync_dir",
    "image_path",
    "image_paths",
    "keep_aside",
    "make_folders",
    "run_header_bytes",
    "staged_path",
    "listed_mcap",
    "listed_part",
    "manifest_path",
    "mcap_dir",
    "answer_cache_path",
    "episode_terms_path",
    "metric_cache_path",
    "result_cache_path",
    "step_counts_path",
    "schema_cache_path",
    "partition",
    "partition_dir",
    "quarantine_path",
    "reference_tables",
    "run_json_path",
    "runs_path",
    "ssm_path",
    "tasks_path",
    "truncate",
    "write_all",
    "write_atomic",
    # batches and where they run (vge replay, vge sweep), file names from ids
    "Executor",
    "LambdaBatch",
    "LambdaTask",
    "in_order",
    "make_executor",
    "start_method",
    "replay_batch",
    "replay_lambdas",
    "safe_file_name",
    "worker_state",
    "Ready",
    # the JSON Schemas
    "record_schema",
    "schema_documents",
    "write_schemas",
]

__getattr__, __dir__ = lazy_names(__name__, __file__)
