"""A run directory written the one way (PROTOCOL §1.4, §10.2), by every tool that writes one:
`vge run`, `vge play` and `vge synth`.

- `run.json` is replaced whole (`run_header_bytes`), never written in place.
- Each finished episode is one line, appended in a single write and synced to disk, so a
  crash leaves whole lines and at most one last line cut short.
- The torn-line rule (`repair`): a last line without its newline is complete when it reads
  as an episode record, and only gets its newline; otherwise it was cut short by a crash and
  is cut off the file (kept in `aside/episodes-tail.<n>.jsonl` when the writer has a place
  for it: `vge play`'s journals hold the same steps, `vge run` plays the episode again).
- `rewrite` replaces the episodes file whole, in an order the caller chooses.
- `stream` writes a file that nobody reads before it is complete (`vge synth` writes into
  a temporary directory it renames into place): plain or gzip, no sync per line.
"""

from __future__ import annotations

import gzip
from collections.abc import Iterable, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any, BinaryIO

import msgspec

from .._errors import InputError
from ..semantics import RunHeader
from ._decode import decode
from ._durable import append_record, atomic_file, truncate, write_atomic
from ._layout import EPISODES, RUN_JSON
from ._load import episode_decoder, read_run_header, run_header_bytes


class RunDirectory:
    """RUN_DIR as a writer sees it: its header and its episodes file (see the module
    docstring for the rules). `aside` is where a torn last line is kept (None: dropped)."""

    def __init__(self, root: str | Path, *, aside: Path | None = None) -> None:
        self.root = Path(root)
        self.header_path = self.root / RUN_JSON
        self.episodes_path = self.root / EPISODES
        self.aside = aside

    # ------------------------------------------------------------------ the header

    def write_header(self, header: RunHeader | Mapping[str, Any]) -> None:
        write_atomic(self.header_path, run_header_bytes(header))

    def read_header(self) -> RunHeader:
        return read_run_header(self.root)

    # ------------------------------------------------------------------ episodes

    def repair(self) -> Path | None:
        """Apply the torn-line rule to the episodes file; returns where a torn line was
        kept, if one was."""
        path = self.episodes_path
        try:
            data = path.read_bytes()
        except FileNotFoundError:
            return None
        if not data or data.endswith(b"\n"):
            return None
        start = data.rfind(b"\n") + 1
        try:
            decode(episode_decoder, data[start:])
        except msgspec.DecodeError:
            kept = None if self.aside is None else keep_aside(self.aside, "episodes-tail", data[start:])
            truncate(path, start)
            return kept
        append_record(path, b"\n")  # a complete line that only lacks its newline
        return None

    def finished(self) -> dict[str, bytes]:
        """The episodes of the file, id -> line (with its newline), in file order (the first
        line of an id wins), after `repair`. A line that is not an episode record is an
        error naming the file and line."""
        self.repair()
        try:
            data = self.episodes_path.read_bytes()
        except FileNotFoundError:
            return {}
        found: dict[str, bytes] = {}
        for number, line in enumerate(data.splitlines(keepends=True), start=1):
            if not line.strip():
                continue
            try:
                log = decode(episode_decoder, line)
            except msgspec.DecodeError as exc:
                raise InputError(
                    str(self.episodes_path),
                    f"not an episode ({exc}); remove the line to play the episode again",
                    line=number,
                ) from None
            found.setdefault(log.episode_id, line)
        return found

    def append(self, line: bytes) -> None:
        """One finished episode's line (with its newline): one write, synced."""
        append_record(self.episodes_path, line, create=True)

    def rewrite(self, lines: Iterable[bytes]) -> None:
        """Replace the episodes file whole with `lines` (each with its newline)."""
        write_atomic(self.episodes_path, b"".join(lines))

    @contextmanager
    def stream(self, *, compress: bool = False) -> Iterator[BinaryIO]:
        """A new episodes file to write line by line (`episodes.jsonl.gz` when `compress`:
        no name or time in the gzip header, so the bytes depend on the lines alone)."""
        self.root.mkdir(parents=True, exist_ok=True)
        if not compress:  # whole or not at all, never through a link (`atomic_file`)
            with atomic_file(self.episodes_path, sync=False) as fh:
                yield fh
            return
        with (
            atomic_file(self.root / f"{EPISODES}.gz", sync=False) as raw,
            gzip.GzipFile(filename="", mode="wb", fileobj=raw, mtime=0, compresslevel=6) as gz,
        ):
            yield gz  # type: ignore[misc]


def keep_aside(folder: Path, stem: str, data: bytes) -> Path:
    """Keep `data` in `folder/<stem>.<n>.jsonl`, the first such name free (never read again
    by the replay; nothing a crash or a discard removes is lost)."""
    folder.mkdir(parents=True, exist_ok=True)
    n = 1
    while (target := folder / f"{stem}.{n}.jsonl").exists():
        n += 1
    write_atomic(target, data)
    return target


__all__ = ["EPISODES", "RUN_JSON", "RunDirectory", "keep_aside"]
