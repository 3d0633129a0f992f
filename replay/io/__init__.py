"""Input and output: loading benchmarks and logs, batches, Parquet parts, manifest, quarantine,
MCAP, the runner, and the one run-directory writer with its crash-safe file primitives.

The names below are public for the tools that write run directories (`vge run`, `vge play`,
`vge synth`) and for the benchmarks (the episode decoder, a worker's state, the reference's
tables of a batch); the rest of the layer is reached through `replay`'s own exports.
"""

from typing import TYPE_CHECKING

from .._lazy import lazy_names

if TYPE_CHECKING:  # the names, imported when first used (`lazy_names`)
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
    from ._load import episode_decoder
    from ._manifest import runs_table
    from ._rundir import EPISODES, RUN_JSON, RunDirectory, keep_aside
    from ._worker import reference_tables, worker_state

__all__ = [
    "EPISODES",
    "RUN_JSON",
    "RunDirectory",
    "append_record",
    "atomic_file",
    "episode_decoder",
    "fsync_dir",
    "keep_aside",
    "make_folders",
    "reference_tables",
    "runs_table",
    "staged_path",
    "truncate",
    "write_all",
    "worker_state",
    "write_atomic",
]

__getattr__, __dir__ = lazy_names(__name__, __file__)
