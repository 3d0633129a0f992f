"""Deterministic replay engine for VGEBench-style logs.

The public API, by layer: `semantics` holds the rules as a readable reference (records,
action grammar, compiled machine, pure step function, planner, classification, episode
replay; PROTOCOL §1-§5), `kernel` the fast batch engine proven identical to it, `io` the
loaders, the runner behind `vge replay` and its outputs (PROTOCOL §7). `replay.env`, imported
on its own (it needs Gymnasium), is the live environment `vge/Device-v0` over the same episode
(PROTOCOL §10). Everything not named here is private.
"""

# The rules (the readable reference engine): records, grammar, machine, step, planner,
# classification, episode replay, and the output rows and their Arrow schema.
from ._errors import (
    ActionError,
    ConfigError,
    InputError,
    Problem,
    RecordTooLarge,
    SSMError,
    TaskError,
    VGEError,
    WorkerError,
)
from ._version import ENGINE_VERSION
from .io._executor import Executor, in_order, make_executor
from .io._fs import Location, is_uri, location
from .io._lambdas import LambdaBatch, LambdaTask, replay_lambdas

# Input and output: loading and validating, the runner (`vge replay`), manifest, quarantine, MCAP,
# JSON Schemas.
from .io._lines import MAX_RECORD_BYTES, iter_lines
from .io._load import (
    Benchmark,
    decode_state_machine,
    episodes_file,
    load_machine,
    load_ssm,
    read_run_header,
    run_header_bytes,
    validate_benchmark,
    validate_run,
)
from .io._manifest import Manifest, ManifestFile, RunEntry, read_manifest
from .io._mcap import BenchImages, ImageSource, write_episode_mcap
from .io._quarantine import QUARANTINE_KINDS, QuarantineRecord
from .io._runner import replay_runs
from .io._schemas import schema_documents, write_schemas
from .io._task import safe_file_name
from .semantics._classify import Classification, Classifier
from .semantics._episode import (
    EpisodeResult,
    EpisodeSession,
    EpisodeSetup,
    goals_reached,
    parse_log_step,
    refreshed_budget,
    replay_episode,
    setup_episode,
    termination_after,
    timestamp_seconds,
)
from .semantics._machine import (
    CompiledTransition,
    Machine,
    compile_machine,
    rect_contains,
    rect_distance,
    validate_machine,
)
from .semantics._parse import Action, ParsedAction, action_from_record, parse_action
from .semantics._plan import (
    Plan,
    PlannedStep,
    c_opt_dynamic,
    distances,
    plan_goals,
    progressing,
    target_components,
    target_rects,
)
from .semantics._records import (
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
from .semantics._rows import OUTPUT_RECORDS, EpisodeRow, GoalRow, StepRow
from .semantics._step import Outcome, SimState, reset, step
from .semantics._tables import TABLE_ROWS, arrow_schema, rows_to_table
from .semantics._vocab import (
    ACTION_NAMES,
    AXONOMETRIC_VIEWS,
    DEFAULT_LAMBDA,
    ERROR_GROUPS,
    ERROR_TYPES,
    FEEDBACK_KINDS,
    ORTHOGRAPHIC_VIEWS,
    PARSE_DETAILS,
    STANDARD_VIEWS,
    SWITCH_CLASSES,
    TERMINATIONS,
    VIEW_ORDER,
    normalize_param,
    normalize_params,
)

__all__ = [
    "ACTION_NAMES",
    "AXONOMETRIC_VIEWS",
    "DEFAULT_LAMBDA",
    "ENGINE_VERSION",
    "ERROR_GROUPS",
    "ERROR_TYPES",
    "FEEDBACK_KINDS",
    "INPUT_RECORDS",
    "MAX_RECORD_BYTES",
    "ORTHOGRAPHIC_VIEWS",
    "OUTPUT_RECORDS",
    "PARSE_DETAILS",
    "QUARANTINE_KINDS",
    "SCHEMA_VERSION",
    "STANDARD_VIEWS",
    "SWITCH_CLASSES",
    "TABLE_ROWS",
    "TERMINATIONS",
    "VIEW_ORDER",
    "Action",
    "action_from_record",
    "ActionError",
    "ActionRecord",
    "arrow_schema",
    "BBox",
    "BenchImages",
    "Benchmark",
    "c_opt_dynamic",
    "Classification",
    "Classifier",
    "compile_machine",
    "CompiledTransition",
    "ConfigError",
    "Dashboard",
    "DashboardRegion",
    "decode_state_machine",
    "distances",
    "EpisodeLog",
    "EpisodeResult",
    "EpisodeRow",
    "episodes_file",
    "EpisodeSession",
    "EpisodeSetup",
    "Executor",
    "GoalRow",
    "goals_reached",
    "ImageSource",
    "in_order",
    "is_uri",
    "InputError",
    "iter_lines",
    "LambdaBatch",
    "LambdaTask",
    "load_machine",
    "load_ssm",
    "location",
    "Location",
    "LogStep",
    "Machine",
    "make_executor",
    "Manifest",
    "ManifestFile",
    "normalize_param",
    "normalize_params",
    "Outcome",
    "parse_action",
    "parse_log_step",
    "ParsedAction",
    "Plan",
    "plan_goals",
    "PlannedStep",
    "Problem",
    "progressing",
    "QuarantineRecord",
    "RecordTooLarge",
    "read_manifest",
    "read_run_header",
    "rect_contains",
    "rect_distance",
    "refreshed_budget",
    "replay_episode",
    "replay_lambdas",
    "replay_runs",
    "reset",
    "rows_to_table",
    "run_header_bytes",
    "RunEntry",
    "RunHeader",
    "safe_file_name",
    "schema_documents",
    "setup_episode",
    "SimState",
    "SSMError",
    "StateDef",
    "StateMachine",
    "step",
    "StepRow",
    "target_components",
    "target_rects",
    "Task",
    "TaskError",
    "termination_after",
    "timestamp_seconds",
    "Transition",
    "validate_benchmark",
    "validate_machine",
    "validate_run",
    "VGEError",
    "WorkerError",
    "write_episode_mcap",
    "write_schemas",
]
