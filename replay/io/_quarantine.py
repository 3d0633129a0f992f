"""Quarantine records: every input record `vge replay` could not replay, with the reason.

One JSON object per line of `OUT/quarantine.jsonl`. The `kind` is the contract (a fixed
vocabulary, `QUARANTINE_KINDS`); the `reason` is one line written for people.
"""

from __future__ import annotations

import re
from typing import Annotated

import msgspec
from msgspec import Meta

QUARANTINE_KINDS: dict[str, str] = {
    "malformed_json": "the line is not valid JSON (a truncated line, a stray character...)",
    "invalid_record": "valid JSON, but not an episode record (a missing field, a wrong type)",
    "step_not_object": "an element of `steps` is not a JSON object",
    "unknown_episode": "the episode id is not in the benchmark's tasks.jsonl",
    "unknown_device": "the task's device has no SSM file in BENCH/ssm/ (or its id cannot "
    "name one, or the file links out of BENCH)",
    "invalid_ssm": "the device's SSM file does not load or does not validate",
    "task_error": "the task cannot be played on its device (bad goals, unplannable...)",
    "duplicate_episode": "the episode id already appeared earlier in the same run",
    "truncated_file": "the rest of the file cannot be read (truncated gzip stream, I/O error)",
    "record_too_large": "a line (or a run of blank lines) longer than the maximum size of a "
    "record (--max-record-bytes, 64 MiB by default); the rest of the file is not read",
}
"""Quarantine kind -> what it means (also in docs/REPLAY.md)."""


class QuarantineRecord(msgspec.Struct, kw_only=True):
    """One input record that was not replayed (a line of `OUT/quarantine.jsonl`)."""

    run_id: Annotated[str, Meta(description="Run the record belongs to")]
    file: Annotated[str, Meta(description="Episodes file, as given on the command line")]
    line: Annotated[int, Meta(description="Line number in that file, from 1")]
    episode_id: Annotated[str | None, Meta(description="Episode id, when it could be read")]
    kind: Annotated[str, Meta(description="One of QUARANTINE_KINDS")]
    reason: Annotated[str, Meta(description="What is wrong, in one line")]


_encoder = msgspec.json.Encoder()


def encode_record(record: QuarantineRecord) -> bytes:
    """One JSONL line (with its newline)."""
    return _encoder.encode(record) + b"\n"


class _EpisodeIdOnly(msgspec.Struct):
    episode_id: str | None = None


_id_decoder = msgspec.json.Decoder(_EpisodeIdOnly)
_STEP_NOT_OBJECT = re.compile(r"^Expected `object`, got `(\w+)` - at `\$\.steps\[(\d+)\]`$")


def one_line(text: str, limit: int = 300) -> str:
    """Collapse whitespace so a reason stays on one line; cap its length."""
    flat = " ".join(text.split())
    return flat if len(flat) <= limit else flat[: limit - 3] + "..."


def classify_decode_error(line: bytes, exc: msgspec.DecodeError) -> tuple[str, str, str | None]:
    """(kind, reason, episode_id if readable) for an episode line msgspec rejected."""
    message = str(exc)
    if not isinstance(exc, msgspec.ValidationError):
        return "malformed_json", one_line(f"not valid JSON: {message}"), None
    try:
        episode_id = _id_decoder.decode(line).episode_id
    except msgspec.DecodeError:
        episode_id = None
    m = _STEP_NOT_OBJECT.match(message)
    if m:
        return (
            "step_not_object",
            f"step {m.group(2)} is not an object (got {m.group(1)})",
            episode_id,
        )
    return "invalid_record", one_line(message.replace("`", "")), episode_id
