"""The unit of work of `vge replay`: a batch of lines of one episodes file, and its report.

Everything here is plain picklable data, so a batch can be replayed in this process, in a
worker process or in a Ray task by the same function (`replay.io._worker.replay_batch`).
"""

from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, NamedTuple
from urllib.parse import quote

from ..semantics._usage import NO_PRICES, Prices

if TYPE_CHECKING:
    from ._images import ImageSource

_SAFE = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9._+@-]{0,199}$")
NAME_BYTES = 200
"""The longest file name made from an id. What the replay adds around it (the longest:
`<name>.L<line>.mcap.tmp.tmp`, or `episodes-run_id=<run_id>` in `.replay/trash`) stays
within the 255 bytes common file systems allow for a name."""
_DIGEST = 32
"""Hex digits of the sha256 of an id in a shortened name (128 bits: two ids never share one)."""


def safe_file_name(name: str) -> str:
    """A file name for an id (PROTOCOL §7.8): unchanged when harmless, else
    percent-encoded; a name that would pass `NAME_BYTES` keeps its first characters and
    ends with `=` and the sha256 of the whole id (no other name holds `=`), so it stays
    unique and the same on every run."""
    if _SAFE.match(name):
        return name
    encoded = _encoded(name)
    if len(encoded) <= NAME_BYTES:
        return encoded
    budget = NAME_BYTES - _DIGEST - 1
    head = ""
    for k, ch in enumerate(name[:budget]):  # whole characters, so that the head decodes
        piece = _encoded(ch) if k == 0 else quote(ch, safe="")
        if len(head) + len(piece) > budget:
            break
        head += piece
    return f"{head}={hashlib.sha256(name.encode()).hexdigest()[:_DIGEST]}"


def _encoded(name: str) -> str:
    encoded = quote(name, safe="")
    return "%2E" + encoded[1:] if encoded.startswith(".") else encoded


def part_name(index: int) -> str:
    """The Parquet part written for batch `index` of a run (per table)."""
    return f"part-{index:05d}.parquet"


@dataclass(frozen=True)
class RunContext:
    """What a batch needs to know about its run (the same for every batch of the run)."""

    run_id: str
    model: str
    agent_kind: str
    run_lambda: float | None
    option_lambda: float | None
    file: str  # the episodes file, as given (quarantine records name it)
    staging: str  # the run's staging directory: <table>/part-NNNNN.parquet, mcap/
    row_group_rows: int
    mcap: bool = False
    mcap_episodes: frozenset[str] | None = None
    image_source: ImageSource | None = None
    prices: Prices = NO_PRICES  # the run's, for the cost columns (PROTOCOL §1.4)

    def wants_mcap(self, episode_id: str) -> bool:
        return self.mcap and (self.mcap_episodes is None or episode_id in self.mcap_episodes)


@dataclass(frozen=True)
class BatchTask:
    """Lines `lines` (numbered from 1 in their file, blank ones left out) of one run, batch
    number `index` of that run. `skip` holds lines the main process found to repeat an
    earlier episode: they are not replayed (see `RunJob.take`)."""

    ctx: RunContext
    bench: str
    index: int
    lines: tuple[tuple[int, bytes], ...]
    skip: frozenset[int] = frozenset()

    def skipping(self, lines: frozenset[int]) -> BatchTask:
        return replace(self, skip=lines)


class LineOutcome(NamedTuple):
    """What happened to one line: replayed (`kind` None), quarantined, or `skipped`."""

    line: int
    episode_id: str | None
    decoded: bool  # a well-formed episode record (takes part in the duplicate check)
    kind: str | None
    reason: str | None
    n_steps: int = 0
    n_goals: int = 0
    mcap_tmp: str | None = None  # file name in the run's staging mcap/ directory


SKIPPED = "skipped"
"""Outcome kind of a line in `BatchTask.skip` (the main process records why)."""


@dataclass
class BatchCounts:
    """Counts of the rows a batch wrote (the manifest's per-run counts add them up)."""

    steps: int = 0
    truncated: int = 0
    diverged: int = 0
    compared: int = 0
    episodes_diverged: int = 0
    goals: int = 0
    mcap_files: int = 0  # counted by the main process as it publishes them
    by_field: dict[str, int] = field(default_factory=dict)

    def add(self, other: BatchCounts) -> None:
        for name in ("steps", "truncated", "diverged", "compared", "episodes_diverged", "goals"):
            setattr(self, name, getattr(self, name) + getattr(other, name))
        for key, value in other.by_field.items():
            self.by_field[key] = self.by_field.get(key, 0) + value


@dataclass
class BatchReport:
    """What a replayed batch did: per line outcomes, the part files it wrote (table ->
    rows; no file when a table has no row), its counts, and where it ran."""

    index: int
    outcomes: list[LineOutcome]
    parts: dict[str, int]
    counts: BatchCounts
    node: str = ""


@dataclass(frozen=True)
class BatchFailure:
    """An unexpected error inside a batch, carried back as plain data."""

    index: int
    line: int | None
    message: str
    details: str
    node: str = ""
