"""The run directory `vge run` writes: exactly what `vge replay` reads (PROTOCOL §1.4), plus
`failures.jsonl` for the episodes that ended on an infrastructure failure.

Crash safety: each finished episode is one line, appended with a single write and synced to
disk, so a crash loses at most the episodes in flight; a line cut short by a crash (the last
one, without its newline) is dropped when the run is resumed. When a run completes, the
episodes file is rewritten in the order of the selection (a new file renamed over the old),
so its bytes do not depend on the concurrency or on interruptions. `run.json` is always
replaced whole, never written in place.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import msgspec

import replay

from .._durable import append_record, truncate, write_atomic
from .._errors import RunDirError

EPISODES = "episodes.jsonl"
FAILURES = "failures.jsonl"
RUN_JSON = "run.json"


class FailureRecord(msgspec.Struct, frozen=True):
    """One line of `failures.jsonl`: an episode that ended on an infrastructure failure
    (PROTOCOL §1.4). It is not in the episodes file and is played again by `--resume`."""

    episode_id: str
    """The episode."""
    steps: int
    """Steps the agent had taken when the request failed (they are discarded)."""
    reason: str
    """What failed, in one line."""


_episode_decoder = msgspec.json.Decoder(replay.EpisodeLog)
_encoder = msgspec.json.Encoder()


class RunDir:
    """RUN_DIR: its header, the finished episodes (as their lines) and the failures."""

    def __init__(self, root: Path) -> None:
        self.root = root
        self.episodes_path = root / EPISODES
        self.failures_path = root / FAILURES
        self.header_path = root / RUN_JSON

    # ------------------------------------------------------------------ starting

    def create(self) -> None:
        """A new run: RUN_DIR must not hold one already."""
        if self.root.exists() and not self.root.is_dir():
            raise RunDirError(f"{self.root}: not a directory")
        if self.root.is_dir() and any(self.root.iterdir()):
            raise RunDirError(
                f"{self.root} is not empty: --resume completes the run it holds, or choose "
                "another --out"
            )
        self.root.mkdir(parents=True, exist_ok=True)

    def read_header(self) -> replay.RunHeader:
        if not self.header_path.is_file():
            raise RunDirError(f"{self.root}: no run.json, nothing to resume")
        return replay.read_run_header(self.root)

    def read_finished(self) -> dict[str, bytes]:
        """The finished episodes, id -> line (with its newline), in file order. A last line
        cut short by a crash is removed from the file."""
        try:
            data = self.episodes_path.read_bytes()
        except FileNotFoundError:
            return {}
        cut = data.rfind(b"\n") + 1
        if cut < len(data):
            truncate(self.episodes_path, cut)
        finished: dict[str, bytes] = {}
        for number, line in enumerate(data[:cut].splitlines(keepends=True), start=1):
            if not line.strip():
                continue
            try:
                log = _episode_decoder.decode(line)
            except msgspec.DecodeError as exc:
                raise RunDirError(
                    f"{self.episodes_path}:{number}: not an episode ({exc}); remove the line "
                    "to play the episode again"
                ) from None
            finished.setdefault(log.episode_id, line)
        return finished

    # ------------------------------------------------------------------ while running

    def write_header(self, header: replay.RunHeader) -> None:
        write_atomic(self.header_path, replay.run_header_bytes(header))

    def append_episode(self, line: bytes) -> None:
        append_record(self.episodes_path, line, create=True)

    def append_failure(self, record: FailureRecord) -> None:
        append_record(self.failures_path, _encoder.encode(record) + b"\n", create=True)

    # ------------------------------------------------------------------ completing

    def rewrite(
        self, order: Iterable[str], finished: dict[str, bytes], failures: dict[str, FailureRecord]
    ) -> None:
        """The episodes file in the selection's order; the failures file likewise (removed
        when there is none)."""
        order = list(order)
        write_atomic(self.episodes_path, b"".join(finished[e] for e in order if e in finished))
        kept = [failures[e] for e in order if e in failures and e not in finished]
        if kept:
            write_atomic(self.failures_path, b"".join(_encoder.encode(r) + b"\n" for r in kept))
        else:
            self.failures_path.unlink(missing_ok=True)


__all__ = ["EPISODES", "FAILURES", "RUN_JSON", "FailureRecord", "RunDir"]
