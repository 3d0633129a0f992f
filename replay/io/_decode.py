"""Decoding a JSON input with a bound on its nesting (PROTOCOL §1.5).

The decoder recurses once per level and gives up where Python's stack does, so the verdict
on a deep value would depend on who decodes it (the main process, a worker, a Ray task): the
depth is checked first, on the bytes, and a deeper value is malformed everywhere."""

from __future__ import annotations

from typing import TypeVar

import msgspec

from ..kernel import nested_beyond

T = TypeVar("T")

MAX_DEPTH = 256
"""Levels of nested arrays and objects a JSON input may have (a record needs fewer than 10)."""


def decode(decoder: msgspec.json.Decoder[T], data: bytes) -> T:
    """`decoder.decode(data)`, raising `msgspec.DecodeError` for a value nested deeper than
    `MAX_DEPTH` (with its byte offset, like the decoder's own messages)."""
    at = nested_beyond(data, MAX_DEPTH)
    if at >= 0:
        raise msgspec.DecodeError(f"JSON is nested deeper than {MAX_DEPTH} levels (byte {at})")
    try:
        return decoder.decode(data)
    except RecursionError:  # only a caller already deep in its stack gets here
        raise msgspec.DecodeError("JSON is nested too deeply for the stack left") from None
