"""The run directory `vge run` writes: exactly what `vge replay` reads (PROTOCOL §1.4), plus
`failures.jsonl` for the episodes that ended on an infrastructure failure.

The run's header and episodes are written by the replay's one run-directory writer
(`replay.io.RunDirectory`: whole-file replacement of run.json, one synced line per finished
episode, the torn-line rule). A crash loses at most the episodes in flight; a line cut short
by one is dropped when the run is resumed, and its episode played again. When a run
completes, the episodes file is rewritten in the order of the selection, so its bytes do
not depend on the concurrency or on interruptions.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import msgspec

import replay
from replay.io import FAILURES, RUN_JSON, RunDirectory, append_record, write_atomic

from .._errors import RunDirError


class FailureRecord(msgspec.Struct, frozen=True):
    """One line of `failures.jsonl`: an episode that ended on an infrastructure failure
    (PROTOCOL §1.4). It is not in the episodes file and is played again by `--resume`."""

    episode_id: str
    """The episode."""
    steps: int
    """Steps the agent had taken when the request failed (they are discarded)."""
    reason: str
    """What failed, in one line."""


_encoder = msgspec.json.Encoder()


class RunDir(RunDirectory):
    """RUN_DIR: its header, the finished episodes (as their lines) and the failures."""

    def __init__(self, root: Path) -> None:
        super().__init__(root)
        self.failures_path = self.root / FAILURES

    def check_new(self) -> None:
        """A new run may go here: RUN_DIR does not exist or is an empty directory."""
        if self.root.exists() and not self.root.is_dir():
            raise RunDirError(f"{self.root}: not a directory")
        if self.root.is_dir() and any(self.root.iterdir()):
            raise RunDirError(
                f"{self.root} is not empty: --resume completes the run it holds, or choose "
                "another --out"
            )

    def create(self) -> None:
        """A new run: RUN_DIR must not hold one already."""
        self.check_new()
        self.root.mkdir(parents=True, exist_ok=True)

    def read_header(self) -> replay.RunHeader:
        if not self.header_path.is_file():
            raise RunDirError(f"{self.root}: no {RUN_JSON}, nothing to resume")
        return super().read_header()

    def append_failure(self, record: FailureRecord) -> None:
        append_record(self.failures_path, _encoder.encode(record) + b"\n", create=True)

    def rewrite_in_order(
        self, order: Iterable[str], finished: dict[str, bytes], failures: dict[str, FailureRecord]
    ) -> None:
        """The episodes file in the selection's order; the failures file likewise (removed
        when there is none)."""
        order = list(order)
        self.rewrite(finished[e] for e in order if e in finished)
        kept = [failures[e] for e in order if e in failures and e not in finished]
        if kept:
            write_atomic(self.failures_path, b"".join(_encoder.encode(r) + b"\n" for r in kept))
        else:
            self.failures_path.unlink(missing_ok=True)


__all__ = ["FAILURES", "FailureRecord", "RunDir"]
