"""Deterministic replay engine for VGEBench-style logs.

Public API: records (SPEC 1), the action parser (SPEC 2), the compiled machine and the pure
step function (SPEC 3), the planner (SPEC 4), classification and episode replay (SPEC 5),
and the loaders/validators. Everything else is private.
"""

from ._classify import Classification, Classifier
from ._episode import (
    EpisodeResult,
    EpisodeSetup,
    parse_log_step,
    replay_episode,
    setup_episode,
    timestamp_seconds,
)
from ._errors import ConfigError, InputError, Problem, SSMError, TaskError, VGEError
from ._load import (
    Benchmark,
    decode_state_machine,
    episodes_file,
    iter_lines,
    load_machine,
    load_ssm,
    read_run_header,
    validate_benchmark,
    validate_run,
)
from ._machine import (
    CompiledTransition,
    Machine,
    compile_machine,
    rect_contains,
    rect_distance,
    validate_machine,
)
from ._parse import PARSE_DETAILS, Action, ParsedAction, action_from_record, parse_action
from ._plan import (
    Plan,
    PlannedStep,
    c_opt_dynamic,
    distances,
    plan_goals,
    progressing,
    target_components,
    target_rects,
)
from ._records import (
    INPUT_RECORDS,
    SCHEMA_VERSION,
    ActionRecord,
    BBox,
    Dashboard,
    DashboardRegion,
    EpisodeLog,
    LogStep,
    RunHeader,
    StateDef,
    StateMachine,
    Task,
    Transition,
)
from ._rows import OUTPUT_RECORDS, EpisodeRow, GoalRow, StepRow
from ._step import Outcome, SimState, reset, step
from ._vocab import (
    ACTION_NAMES,
    AXONOMETRIC_VIEWS,
    DEFAULT_LAMBDA,
    ERROR_GROUPS,
    ERROR_TYPES,
    FEEDBACK_KINDS,
    ORTHOGRAPHIC_VIEWS,
    STANDARD_VIEWS,
    SWITCH_CLASSES,
    TERMINATIONS,
    VIEW_ORDER,
    normalize_param,
    normalize_params,
)

ENGINE_VERSION = "0.1.0"
"""Changes whenever replay output for the same inputs may change (invalidates caches)."""

__all__ = [
    "ACTION_NAMES",
    "AXONOMETRIC_VIEWS",
    "Action",
    "ActionRecord",
    "BBox",
    "Benchmark",
    "Classification",
    "Classifier",
    "CompiledTransition",
    "ConfigError",
    "DEFAULT_LAMBDA",
    "Dashboard",
    "DashboardRegion",
    "ENGINE_VERSION",
    "ERROR_GROUPS",
    "ERROR_TYPES",
    "EpisodeLog",
    "EpisodeResult",
    "EpisodeRow",
    "EpisodeSetup",
    "FEEDBACK_KINDS",
    "GoalRow",
    "INPUT_RECORDS",
    "InputError",
    "LogStep",
    "Machine",
    "ORTHOGRAPHIC_VIEWS",
    "OUTPUT_RECORDS",
    "Outcome",
    "PARSE_DETAILS",
    "ParsedAction",
    "Plan",
    "PlannedStep",
    "Problem",
    "RunHeader",
    "SCHEMA_VERSION",
    "SSMError",
    "STANDARD_VIEWS",
    "SWITCH_CLASSES",
    "SimState",
    "StateDef",
    "StateMachine",
    "StepRow",
    "TERMINATIONS",
    "Task",
    "TaskError",
    "Transition",
    "VGEError",
    "VIEW_ORDER",
    "action_from_record",
    "c_opt_dynamic",
    "compile_machine",
    "decode_state_machine",
    "distances",
    "episodes_file",
    "iter_lines",
    "load_machine",
    "load_ssm",
    "normalize_param",
    "normalize_params",
    "parse_action",
    "parse_log_step",
    "plan_goals",
    "progressing",
    "read_run_header",
    "replay_episode",
    "reset",
    "setup_episode",
    "step",
    "target_components",
    "target_rects",
    "timestamp_seconds",
    "validate_benchmark",
    "validate_machine",
    "validate_run",
    "rect_contains",
    "rect_distance",
]

from ._tables import TABLE_ROWS, arrow_schema, rows_to_table  # noqa: E402

__all__ += ["TABLE_ROWS", "arrow_schema", "rows_to_table"]

from ._schemas import schema_documents, write_schemas  # noqa: E402

__all__ += ["schema_documents", "write_schemas"]

# --- replay runner (vge replay): batches, workers, quarantine, manifest, MCAP
from ._errors import WorkerError  # noqa: E402
from ._manifest import Manifest, ManifestFile, RunEntry, read_manifest  # noqa: E402
from ._mcap import BenchImages, ImageSource, write_episode_mcap  # noqa: E402
from ._quarantine import QUARANTINE_KINDS, QuarantineRecord  # noqa: E402
from ._runner import replay_runs  # noqa: E402

__all__ += [
    "BenchImages",
    "ImageSource",
    "Manifest",
    "ManifestFile",
    "QUARANTINE_KINDS",
    "QuarantineRecord",
    "RunEntry",
    "WorkerError",
    "read_manifest",
    "replay_runs",
    "write_episode_mcap",
]
