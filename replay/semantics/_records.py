"""Typed, versioned records for every input format (PROTOCOL §1).

The JSON Schemas in `schemas/` are generated from these classes (`replay.io.write_schemas`),
and a test fails when the committed files drift. Field descriptions live in `Meta` so
they reach the schemas.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

import msgspec
from msgspec import Meta, field

SCHEMA_VERSION = 1
"""Version of the input and output record formats; bump on any incompatible change."""

Scalar = str | int | float


def _doc(text: str) -> Meta:
    return Meta(description=text)


# ---------------------------------------------------------------------------- SSM / UCSM


class BBox(msgspec.Struct, forbid_unknown_fields=False):
    """Where a component can be clicked in one view."""

    coordinate: Annotated[
        list[float],
        _doc("[x, y, w, h, W, H]: top-left corner, width and height in pixels of a W x H image"),
    ]
    view: Annotated[str, _doc("The view this box is drawn on (front, back, ..., dashboard)")]


class Transition(msgspec.Struct):
    """One edge of the state machine, triggered by a component (or immediate/timed_wait)."""

    next_state: Annotated[str, _doc("State entered when the transition fires")]
    transition_description: Annotated[str, _doc("What the user observes; shown as feedback")] = ""
    bbox: Annotated[list[BBox], _doc("Boxes of the component, one per view it is visible in")] = []
    atomic_action: Annotated[
        str | None, _doc("press, rotate, push, pull or grasp (case-insensitive)")
    ] = None
    parameter: Annotated[
        list[Scalar] | None,
        _doc("Required params; '*' matches any value; empty/missing matches any"),
    ] = None


class StateDef(msgspec.Struct):
    """A state: its description and its transitions, keyed by component name."""

    description: Annotated[str, _doc("Natural-language description of the device status")] = ""
    on: Annotated[
        dict[str, list[Transition]],
        _doc("component -> transitions; 'immediate' and 'timed_wait' are not components"),
    ] = {}
    is_error: Annotated[bool, _doc("Marks an error state (like a state named 'Error')")] = False


class ImageRef(msgspec.Struct):
    """A rendered view image of the device."""

    path: Annotated[str, _doc("Path relative to the benchmark directory")]
    width: Annotated[int, _doc("Image width in pixels")]
    height: Annotated[int, _doc("Image height in pixels")]


class DashboardRegion(msgspec.Struct):
    """A region of an orthographic view whose zoomed-in view is the dashboard."""

    view: Annotated[str, _doc("Orthographic view holding the region")]
    coordinate: Annotated[list[float], _doc("[x, y, w, h, W, H] as for bboxes")]


class Dashboard(msgspec.Struct):
    """The dashboard extension: where the (initially locked) dashboard can be unlocked."""

    regions: Annotated[list[DashboardRegion], _doc("Dashboard regions")] = []


class StateMachine(msgspec.Struct):
    """A Specific State Machine (SSM) or, without bboxes, a category template (UCSM).

    The paper's format, accepted verbatim; the keys after `states` are optional extensions.
    Unknown keys (the paper's listing has `path`) are ignored.
    """

    name: Annotated[str, _doc("Category name, e.g. ElectricKettle")]
    initial_state: Annotated[str, _doc("State the device starts in")]
    states: Annotated[dict[str, StateDef], _doc("State name -> definition")]
    device_id: Annotated[str | None, _doc("Device identifier (default: file stem)")] = None
    category: Annotated[str | None, _doc("Category (default: name)")] = None
    views: Annotated[
        list[str] | None, _doc("Views the device offers (default: the eight standard views)")
    ] = None
    images: Annotated[dict[str, ImageRef] | None, _doc("view -> rendered image")] = None
    dashboard: Annotated[Dashboard | None, _doc("Dashboard regions, for large devices")] = None
    schema_version: Annotated[int, _doc("Record format version")] = SCHEMA_VERSION


# --------------------------------------------------------------------------------- tasks


class Task(msgspec.Struct):
    """One episode definition (a line of `tasks.jsonl`)."""

    episode_id: Annotated[str, _doc("Unique episode identifier")]
    device_id: Annotated[str, _doc("Device whose SSM the episode runs on")]
    goals: Annotated[list[str], _doc("Ordered goal states; goal i completes when it is entered")]
    instructions: Annotated[list[str], _doc("Instruction shown while goal i is current")] = []
    initial_view: Annotated[str, _doc("View the agent starts in")] = "front"
    initial_state: Annotated[str | None, _doc("Overrides the SSM's initial state")] = None
    lam: Annotated[float | None, _doc("Budget redundancy factor lambda for this task")] = field(
        default=None, name="lambda"
    )
    c_opt: Annotated[
        list[int] | None, _doc("Optional stated C_opt per goal; checked against the planner")
    ] = None
    schema_version: Annotated[int, _doc("Record format version")] = SCHEMA_VERSION


# ------------------------------------------------------------------------------ run logs


class RunHeader(msgspec.Struct):
    """`RUN/run.json`: who produced a run and how."""

    run_id: Annotated[str, _doc("Unique run identifier (also the partition key)")]
    model: Annotated[str, _doc("Model (or participant group) name")]
    agent_kind: Annotated[Literal["vlm", "human", "scripted"], _doc("vlm, human or scripted")]
    lam: Annotated[float | None, _doc("lambda the run was executed with")] = field(
        default=None, name="lambda"
    )
    meta: Annotated[dict[str, Any], _doc("Free-form run facets (history length, ...)")] = {}
    schema_version: Annotated[int, _doc("Record format version")] = SCHEMA_VERSION


RUN_TOTALS: tuple[str, ...] = (
    "episodes_selected",
    "episodes",
    "infrastructure_failures",
    "tasks_skipped",
    "complete",
    "steps",
    "prompt_tokens",
    "completion_tokens",
    "latency_seconds",
    "cost_usd",
    "source_lines_unread",
)
"""Keys of run.json's meta that count what a run did or was asked to play (PROTOCOL §10.2),
not how it was set up: `vge run` writes them, and runs that differ only in them (and the
seed) are repeats of one setting."""
MAX_META_KEYS = 256
"""The most keys a run.json's meta may hold (PROTOCOL §1.5): each scalar one is a column of
the runs table, which every command and page reads."""
MAX_META_BYTES = 1 << 16
"""The most bytes a run.json's meta may take, as compact JSON (PROTOCOL §1.5)."""
INT64 = (-(1 << 63), (1 << 63) - 1)
"""The integers the tables can hold: a meta integer outside them is refused (PROTOCOL §1.5)."""


def meta_problem(meta: dict[str, Any]) -> str | None:
    """What makes a run.json's meta too wide or unwritable (PROTOCOL §1.5), in one line; None
    when nothing does. The walk is linear in what the decoder already read."""
    if len(meta) > MAX_META_KEYS:
        return f"meta has {len(meta):,} keys; at most {MAX_META_KEYS}"
    stack: list[tuple[str, Any]] = [("meta", meta)]
    while stack:
        where, value = stack.pop()
        if isinstance(value, int) and not INT64[0] <= value <= INT64[1]:
            bits = value.bit_length() + (value < 0)
            return f"{where} is an integer of {bits} bits; the tables hold 64 (signed)"
        if isinstance(value, dict):
            stack.extend((f"{where}.{k}", v) for k, v in reversed(value.items()))
        elif isinstance(value, list):
            stack.extend((f"{where}[{i}]", v) for i, v in reversed(list(enumerate(value))))
    size = len(msgspec.json.encode(meta))
    if size > MAX_META_BYTES:
        return f"meta takes {size:,} bytes as JSON; at most {MAX_META_BYTES:,}"
    return None


MAX_TOKENS = 1 << 40
"""The most tokens a step may record (PROTOCOL §1.4): sums over the steps of a record of at most
64 MiB stay far within the 64-bit integers of the tables."""
Tokens = Annotated[int, Meta(ge=0, le=MAX_TOKENS)]
Seconds = Annotated[float, Meta(ge=0)]


class ActionRecord(msgspec.Struct):
    """An already-structured action, as human logs have."""

    type: Annotated[str, _doc("Press, Rotate, Push, Pull, Grasp, Switch_view or Timed_wait")]
    coord: Annotated[list[float] | None, _doc("[x, y] on the 0..1000 scale, or null")] = None
    params: Annotated[list[Scalar], _doc("Action parameters")] = []


class LogStep(msgspec.Struct):
    """One logged agent response: raw text `output` or a structured `action`."""

    output: Annotated[str | None, _doc("Raw model text (Thinking: ... Action: ...)")] = None
    action: Annotated[ActionRecord | None, _doc("Structured action (instead of output)")] = None
    view: Annotated[str | None, _doc("Recorded view after the step (compared, not trusted)")] = None
    feedback: Annotated[
        str | None, _doc("Recorded feedback kind or text (compared, not trusted)")
    ] = None
    state: Annotated[str | None, _doc("Recorded state after the step (compared, not trusted)")] = (
        None
    )
    timestamp: Annotated[
        float | str | None, _doc("Seconds since the epoch or ISO 8601 time of the step")
    ] = None
    prompt_tokens: Annotated[
        Tokens | None, _doc("Tokens of the request the model answered (as its API counted them)")
    ] = None
    completion_tokens: Annotated[Tokens | None, _doc("Tokens of the model's answer")] = None
    latency_seconds: Annotated[
        Seconds | None, _doc("Seconds the model took to answer (the request that succeeded)")
    ] = None


class Continuation(msgspec.Struct):
    """How an episode of a continuation run (`vge run --from`, PROTOCOL §10.4) was made from
    the same episode of another run."""

    prefix_steps: Annotated[
        int, Meta(ge=0), _doc("The first N steps repeat the source run's episode (origin prefix)")
    ]
    fixed: Annotated[
        bool, _doc("Step N is the planner's optimal step from there (origin fix, PROTOCOL §4.5)")
    ]
    continued: Annotated[
        bool,
        _doc(
            "The agent was handed the episode after them; false: the source's episode copied as "
            "it was (no error to cut at, or it ended within the first K steps)"
        ),
    ]
    source_success: Annotated[bool, _doc("The source run's episode succeeded (its replay)")]


class EpisodeLog(msgspec.Struct):
    """One line of `episodes.jsonl`."""

    episode_id: Annotated[str, _doc("Episode this log plays (tasks.jsonl)")]
    steps: Annotated[list[LogStep], _doc("Agent responses in order")] = []
    ended: Annotated[
        Literal["context_exceeded"] | None,
        _doc(
            "Why the harness ended the log before any other termination: context_exceeded "
            "(the model refused the next request as longer than its context window)"
        ),
    ] = None
    continuation: Annotated[
        Continuation | None,
        _doc("Set in a continuation run only: how the episode continues another run's"),
    ] = None

    def __post_init__(self) -> None:
        # Checked when the line is decoded: a bad one is an invalid_record (PROTOCOL §7.6).
        c = self.continuation
        if c is None:
            return
        n = len(self.steps)
        if c.prefix_steps + c.fixed > n:
            raise ValueError(
                f"continuation: {c.prefix_steps} prefix step(s)"
                + (" and a fix" if c.fixed else "")
                + f" in a log of {n} step(s)"
            )
        if not c.continued and (c.fixed or c.prefix_steps != n):
            raise ValueError("continuation: a copied episode (continued false) is its prefix alone")


INPUT_RECORDS: dict[str, type] = {
    "ssm": StateMachine,
    "ucsm": StateMachine,
    "task": Task,
    "run": RunHeader,
    "episode": EpisodeLog,
}
"""Input record types by schema name (`schemas/<name>.schema.json`)."""
