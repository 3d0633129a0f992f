"""Times as the exports write them: only recorded ones (no clock is read), in ISO 8601."""

from __future__ import annotations

import math
from datetime import UTC, datetime

EPOCH = "1970-01-01T00:00:00+00:00"
"""What a required time says when nothing was recorded."""


def iso_time(seconds: float | None) -> str | None:
    """A recorded time (seconds since the epoch) in ISO 8601, UTC, to the millisecond (the
    precision the harnesses record); None when there is none."""
    if seconds is None or not math.isfinite(seconds):
        return None
    return datetime.fromtimestamp(seconds, tz=UTC).isoformat(timespec="milliseconds")


__all__ = ["EPOCH", "iso_time"]
