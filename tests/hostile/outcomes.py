"""What a replay of hostile input left: its quarantine, its counts, its one-line error."""

from __future__ import annotations

import json
from pathlib import Path

import replay


def quarantine(out: Path) -> list[tuple[int, str]]:
    lines = (out / "quarantine.jsonl").read_text().splitlines()
    return [(r["line"], r["kind"]) for r in map(json.loads, lines)]


def counts(out: Path) -> replay.io._manifest.RunCounts:
    manifest = replay.read_manifest(out)
    assert manifest is not None
    return manifest.runs[0].counts


def one_line_error(stderr: str) -> str:
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), stderr
    return lines[0]
