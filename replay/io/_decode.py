"""Decoding a JSON input with a bound on its nesting, as UTF-8 (PROTOCOL §1.5).

The decoder recurses once per level and gives up where Python's stack does, so the verdict
on a deep value would depend on who decodes it (the main process, a worker, a Ray task): the
depth is checked first, on the bytes, and a deeper value is malformed everywhere. A string
that is not UTF-8 makes msgspec raise `UnicodeDecodeError`, which no reader expects: it is
made a `msgspec.DecodeError` naming the byte, like the decoder's own messages, so every
reader quarantines or reports it as it does any JSON that is not valid."""

from __future__ import annotations

from typing import TypeVar

import msgspec

from ..kernel import nested_beyond

T = TypeVar("T")

MAX_DEPTH = 256
"""Levels of nested arrays and objects a JSON input may have (a record needs fewer than 10)."""


def decode(decoder: msgspec.json.Decoder[T], data: bytes) -> T:
    """`decoder.decode(data)`, raising `msgspec.DecodeError` for a value nested deeper than
    `MAX_DEPTH` or for bytes that are not UTF-8 (each with its byte offset, like the
    decoder's own messages)."""
    at = nested_beyond(data, MAX_DEPTH)
    if at >= 0:
        raise msgspec.DecodeError(f"JSON is nested deeper than {MAX_DEPTH} levels (byte {at})")
    try:
        return decoder.decode(data)
    except RecursionError:  # only a caller already deep in its stack gets here
        raise msgspec.DecodeError("JSON is nested too deeply for the stack left") from None
    except UnicodeDecodeError:
        raise msgspec.DecodeError(f"invalid UTF-8 (byte {not_utf8_at(data)})") from None


def not_utf8_at(data: bytes) -> int:
    """The offset of the first byte of `data` that is not UTF-8 (its length if none is)."""
    try:
        bytes(data).decode("utf-8")
    except UnicodeDecodeError as exc:
        return exc.start
    return len(data)
