"""Where a human run is written by default, and reading its journals back up to their last whole line (they are written with
`replay.io`'s crash-safe writes: whole records in one write and `fsync`, so a crash loses nothing
shown)."""

from __future__ import annotations

from pathlib import Path

import orjson

from .._errors import PlayError

DEFAULT_RUN_DIR = "human-run"
"""Where `vge play` writes without `--out`."""


def journal_header(path: Path) -> str | None:
    """The episode id a journal's first line names (None if it cannot be read)."""
    try:
        with open(path, "rb") as fh:
            first = fh.readline()
        head = orjson.loads(first)
    except (OSError, orjson.JSONDecodeError):
        return None
    episode_id = head.get("episode_id") if isinstance(head, dict) else None
    return episode_id if isinstance(episode_id, str) else None


def journal_steps(path: Path) -> tuple[list[dict], int]:
    """The steps of a journal and the byte size they end at. A last line without its
    newline is a write the app died in (its feedback was never shown) and is left out; a
    complete line that is not a step cannot come from a crash and is an error."""
    data = path.read_bytes()
    steps: list[dict] = []
    pos = data.find(b"\n") + 1  # after the header line
    while pos > 0:
        end = data.find(b"\n", pos)
        if end < 0:
            break
        try:
            step = orjson.loads(data[pos:end])
        except orjson.JSONDecodeError:
            step = None
        if not isinstance(step, dict) or not isinstance(step.get("action"), dict):
            raise PlayError(f"{path}: line {len(steps) + 2} is not a step; discard the episode")
        steps.append(step)
        pos = end + 1
    return steps, pos


__all__ = ["journal_header", "journal_steps"]
