"""One MCAP file per replayed episode, with Foxglove's well-known schemas (PROTOCOL §7).

Channels:
- `/camera` `foxglove.CompressedImage`: the view the agent sees, at step 0 and whenever the
  view changes (only when an image source gives an image for the view);
- `/annotations` `foxglove.ImageAnnotations`, one per scored step: the click, the bboxes of
  the components hit and of the target components, in pixels of that view's image; its
  timestamp is the timestamp of the image it is drawn on;
- `/model` and `/feedback` `foxglove.Log`: the model output, the feedback (level by kind);
- `/step` the step row as JSON (JSON Schema of `StepRow`).
The SSM is an attachment, the episode row a metadata record named `episode`.

Time: the recorded timestamps when every step has one, else step i at i seconds.
Everything is a function of the inputs: the same episode gives the same bytes.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import cache
from typing import TYPE_CHECKING, BinaryIO

import msgspec
from foxglove_schemas_protobuf.CircleAnnotation_pb2 import CircleAnnotation
from foxglove_schemas_protobuf.Color_pb2 import Color
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from foxglove_schemas_protobuf.ImageAnnotations_pb2 import ImageAnnotations
from foxglove_schemas_protobuf.Log_pb2 import Log
from foxglove_schemas_protobuf.Point2_pb2 import Point2
from foxglove_schemas_protobuf.PointsAnnotation_pb2 import PointsAnnotation
from foxglove_schemas_protobuf.TextAnnotation_pb2 import TextAnnotation
from google.protobuf.timestamp_pb2 import Timestamp
from mcap.well_known import MessageEncoding, SchemaEncoding
from mcap.writer import CompressionType, Writer
from mcap_protobuf.schema import build_file_descriptor_set

from .._version import ENGINE_VERSION
from ..semantics import (
    ERROR,
    FEEDBACK_SEVERITY,
    INFO,
    SCALE,
    WARNING,
    Machine,
    Rect,
    StepRow,
    target_rects,
)
from ._file_names import mcap_file_name
from ._fs import Location, location
from ._images import ViewImage
from ._layout import mcap_dir
from ._record_schema import record_schema

if TYPE_CHECKING:
    from ..semantics import EpisodeResult

MCAP_LIBRARY = f"vge-analytics replay {ENGINE_VERSION}"
"""The `library` field of every MCAP file: which engine wrote it."""

TOPICS = ("/camera", "/annotations", "/model", "/feedback", "/step")
"""Channel topics, in the order they are registered."""

SCHEMA_NAMES = {
    "/camera": "foxglove.CompressedImage",
    "/annotations": "foxglove.ImageAnnotations",
    "/model": "foxglove.Log",
    "/feedback": "foxglove.Log",
    "/step": "vge.StepRow",
}

_LEVELS = {INFO: Log.INFO, WARNING: Log.WARNING, ERROR: Log.ERROR}
FEEDBACK_LEVELS = {kind: _LEVELS[severity] for kind, severity in FEEDBACK_SEVERITY.items()}
"""foxglove.Log level of each feedback kind: its severity (PROTOCOL §3.6, §7.8)."""

_TARGET = Color(r=0.15, g=0.75, b=0.3, a=1.0)
_HIT = Color(r=1.0, g=0.6, b=0.0, a=1.0)
_CLICK = Color(r=0.9, g=0.1, b=0.1, a=1.0)
_CLICK_FILL = Color(r=0.9, g=0.1, b=0.1, a=0.35)
_LABEL_BG = Color(r=0.0, g=0.0, b=0.0, a=0.6)
_WHITE = Color(r=1.0, g=1.0, b=1.0, a=1.0)


def episode_mcap_path(out: str | Location, run_id: str, episode_id: str) -> Location:
    """Where `vge replay --mcap` writes an episode's MCAP file."""
    return mcap_dir(location(out), run_id) / mcap_file_name(episode_id)


def attached_ssm(machine: Machine) -> bytes:
    """The SSM attached to an episode's MCAP: its file as it is, else its record as JSON
    (a machine built in memory has no file)."""
    try:
        return location(machine.source).read_bytes()
    except OSError:
        return msgspec.json.encode(machine.ssm)


@cache
def _proto_schema(message_type: type) -> tuple[str, bytes]:
    return message_type.DESCRIPTOR.full_name, build_file_descriptor_set(
        message_type
    ).SerializeToString()


@cache
def _step_json_schema() -> bytes:
    return msgspec.json.encode(record_schema(StepRow), order="deterministic")


_json = msgspec.json.Encoder(order="deterministic")


def _stamp(ns: int) -> Timestamp:
    return Timestamp(seconds=ns // 1_000_000_000, nanos=ns % 1_000_000_000)


def step_times_ns(steps: list[StepRow]) -> list[int]:
    """Log time of each step: recorded timestamps if every step has one, else i seconds."""
    if steps and all(s.timestamp is not None for s in steps):
        return [round(s.timestamp * 1e9) for s in steps]  # type: ignore[operator]
    return [i * 1_000_000_000 for i in range(len(steps))]


def _rect_points(rect: Rect, sx: float, sy: float) -> list[Point2]:
    x0, y0, x1, y1 = rect[0] * sx, rect[1] * sy, rect[2] * sx, rect[3] * sy
    return [Point2(x=x0, y=y0), Point2(x=x1, y=y0), Point2(x=x1, y=y1), Point2(x=x0, y=y1)]


def _annotations(
    machine: Machine, row: StepRow, view: str, stamp: Timestamp, size: tuple[int, int]
) -> ImageAnnotations:
    """Targets (green), components hit (orange) and the click (red), in image pixels."""
    sx, sy = size[0] / SCALE, size[1] / SCALE
    msg = ImageAnnotations(timestamp=stamp)
    if row.state_before is not None and row.goal_state is not None:
        s = machine.state_index[row.state_before]
        goal = machine.state_index[row.goal_state]
        for component, rect in target_rects(machine, s, goal, view):
            _box(msg, rect, sx, sy, _TARGET, f"target: {component}", stamp, 3.0)
    if row.hit_components:
        hit = set(row.hit_components)
        for component, rect in machine.component_rects.get(view, ()):
            if component in hit:
                _box(msg, rect, sx, sy, _HIT, component, stamp, 2.0)
    if row.x is not None and row.y is not None:
        msg.circles.append(
            CircleAnnotation(
                timestamp=stamp,
                position=Point2(x=row.x * sx, y=row.y * sy),
                diameter=max(8.0, 0.02 * max(size)),
                thickness=2.0,
                fill_color=_CLICK_FILL,
                outline_color=_CLICK,
            )
        )
    return msg


def _box(
    msg: ImageAnnotations,
    rect: Rect,
    sx: float,
    sy: float,
    color: Color,
    label: str,
    stamp: Timestamp,
    thickness: float,
) -> None:
    msg.points.append(
        PointsAnnotation(
            timestamp=stamp,
            type=PointsAnnotation.LINE_LOOP,
            points=_rect_points(rect, sx, sy),
            outline_color=color,
            thickness=thickness,
        )
    )
    msg.texts.append(
        TextAnnotation(
            timestamp=stamp,
            position=Point2(x=rect[0] * sx, y=rect[1] * sy),
            text=label,
            font_size=12.0,
            text_color=_WHITE,
            background_color=_LABEL_BG,
        )
    )


class _Channels:
    """Registers each topic's schema and channel on first use (fixed ids by first use)."""

    def __init__(self, writer: Writer) -> None:
        self._writer = writer
        self._ids: dict[str, int] = {}
        self._seq: dict[str, int] = {}

    def _register(self, topic: str, message: object | None) -> int:
        if topic == "/step":
            schema_id = self._writer.register_schema(
                SCHEMA_NAMES[topic], SchemaEncoding.JSONSchema, _step_json_schema()
            )
            encoding = MessageEncoding.JSON
        else:
            name, data = _proto_schema(type(message))
            schema_id = self._writer.register_schema(name, SchemaEncoding.Protobuf, data)
            encoding = MessageEncoding.Protobuf
        return self._writer.register_channel(topic, encoding, schema_id, {})

    def write(self, topic: str, time_ns: int, message: object | None, data: bytes) -> None:
        channel = self._ids.get(topic)
        if channel is None:
            channel = self._ids[topic] = self._register(topic, message)
        seq = self._seq.get(topic, 0)
        self._seq[topic] = seq + 1
        self._writer.add_message(channel, time_ns, data, time_ns, seq)


def write_episode_mcap(
    out: BinaryIO,
    machine: Machine,
    result: EpisodeResult,
    *,
    ssm_bytes: bytes,
    image: Callable[[str], ViewImage | None],
) -> None:
    """Write the MCAP of one replayed episode to a binary stream.

    `image(view)` returns the view's image (or None: no camera message, annotations in the
    image size the SSM declares for the view, else on the 0..1000 agent scale).
    """
    writer = Writer(out, chunk_size=4 * 1024 * 1024, compression=CompressionType.ZSTD)
    writer.start(profile="", library=MCAP_LIBRARY)
    channels = _Channels(writer)
    steps = result.steps
    times = step_times_ns(steps)
    t0 = times[0] if times else 0

    shown_view: str | None = None
    shown_stamp = _stamp(t0)
    shown_size = (SCALE, SCALE)

    def show(view: str, t: int) -> None:
        nonlocal shown_view, shown_stamp, shown_size
        shown_view, shown_stamp = view, _stamp(t)
        got = image(view)
        if got is not None:
            data, fmt, width, height = got
            msg = CompressedImage(timestamp=shown_stamp, frame_id=view, data=data, format=fmt)
            channels.write("/camera", t, msg, msg.SerializeToString())
            shown_size = (width, height)
        else:
            declared = machine.images.get(view)
            shown_size = (declared[1], declared[2]) if declared else (SCALE, SCALE)

    show(result.episode.initial_view, t0)
    for row, t in zip(steps, times, strict=True):
        stamp = _stamp(t)
        if not row.truncated and row.view_before is not None:
            if row.view_before != shown_view:
                show(row.view_before, t)
            ann = _annotations(machine, row, row.view_before, shown_stamp, shown_size)
            channels.write("/annotations", t, ann, ann.SerializeToString())
        text = row.output if row.output is not None else row.action_raw
        model = Log(timestamp=stamp, level=Log.INFO, message=text, name="model")
        channels.write("/model", t, model, model.SerializeToString())
        if not row.truncated and row.feedback_kind is not None:
            feedback = Log(
                timestamp=stamp,
                level=FEEDBACK_LEVELS.get(row.feedback_kind, Log.INFO),
                message=row.feedback_text or "",
                name=row.feedback_kind,
            )
            channels.write("/feedback", t, feedback, feedback.SerializeToString())
        channels.write("/step", t, None, _json.encode(row))

    writer.add_attachment(t0, t0, f"{machine.device_id}.ssm.json", "application/json", ssm_bytes)
    episode = msgspec.to_builtins(result.episode)
    writer.add_metadata(
        "episode",
        {k: v if isinstance(v, str) else _json.encode(v).decode() for k, v in episode.items()},
    )
    writer.finish()
