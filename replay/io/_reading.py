"""Reading the runs: run directories and headers, and an episodes file in batches of lines."""

from __future__ import annotations

import os
import threading
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from queue import Full, Queue

from .._errors import ConfigError, InputError
from ..semantics import Prices, RunHeader, run_prices
from ._file_names import NAME_BYTES
from ._fs import Location, location
from ._layout import run_json_path
from ._lines import iter_lines
from ._load import episodes_file, read_run_header


@dataclass(frozen=True)
class RunInput:
    """A run directory as given, its header (run.json) and its episodes file."""

    run_dir: str  # as given
    header: RunHeader
    episodes: Location
    prices: Prices  # from the header's meta (PROTOCOL §1.4)


def check_run_id(run_id: str, path: Location) -> None:
    """A run id names directories (`run_id=<id>`, `mcap/<id>`): refuse what would break them
    (PROTOCOL §1.5)."""
    size = len(run_id.encode())
    if size > NAME_BYTES:
        raise InputError(
            str(path),
            f"run_id is {size:,} bytes long; it names directories, so at most {NAME_BYTES} "
            "bytes (UTF-8)",
        )
    bad = (
        run_id.startswith(".")
        or any(c in run_id for c in "/\\=%")
        or any(c.isspace() or ord(c) < 32 for c in run_id)
    )
    if bad:
        raise InputError(
            str(path),
            f"run_id {run_id!r} cannot name a partition directory "
            "(no '/', '\\', '=', '%', whitespace, or leading '.')",
        )


def read_runs(run_dirs: Sequence[str | os.PathLike[str]]) -> list[RunInput]:
    runs: dict[str, RunInput] = {}
    for given in run_dirs:
        run_dir = str(given)
        if not location(run_dir).is_dir():
            raise InputError(run_dir, "run directory not found")
        header = read_run_header(run_dir)
        check_run_id(header.run_id, run_json_path(location(run_dir)))
        try:
            prices = run_prices(header.meta)
        except ValueError as exc:
            raise InputError(str(run_json_path(location(run_dir))), str(exc)) from None
        other = runs.get(header.run_id)
        if other is not None:
            raise ConfigError(
                f"run_id {header.run_id!r} appears in two run directories: "
                f"{other.run_dir} and {run_dir}"
            )
        runs[header.run_id] = RunInput(run_dir, header, episodes_file(run_dir), prices)
    return [runs[k] for k in sorted(runs)]


READ_AHEAD = 2
"""Batches the reading thread keeps ready."""
_END = object()


class LineReader:
    """Lines of an episodes file in batches of at most `batch_lines` lines, cut as well once
    they hold `batch_bytes` bytes (so the batches in memory stay bounded whatever the line
    sizes); a read error or a line longer than `max_record_bytes` ends the file (kept in
    `error`).

    A thread reads ahead (`READ_AHEAD` batches): inflating gzip releases the GIL, so the
    reading overlaps the replay of the batches already read."""

    def __init__(
        self, path: Location, batch_lines: int, batch_bytes: int, max_record_bytes: int
    ) -> None:
        self.path = path
        self.batch_lines = batch_lines
        self.batch_bytes = batch_bytes
        self.max_record_bytes = max_record_bytes
        self.last_line = 0
        self.error: InputError | None = None

    def batches(self) -> Iterator[list[tuple[int, bytes]]]:
        ready: Queue[object] = Queue(maxsize=READ_AHEAD)
        stop = threading.Event()
        failure: list[BaseException] = []

        def put(item: object) -> bool:
            while not stop.is_set():
                try:
                    ready.put(item, timeout=0.05)
                    return True
                except Full:
                    continue
            return False

        def produce() -> None:
            try:
                for batch in self._read():
                    if not put(batch):
                        return
            except BaseException as exc:  # handed to the consumer, raised there
                failure.append(exc)
            put(_END)

        reader = threading.Thread(target=produce, name=f"vge-read {self.path.name}", daemon=True)
        reader.start()
        try:
            while True:
                item = ready.get()
                if item is _END:
                    break
                yield item  # type: ignore[misc]
        finally:
            stop.set()
            reader.join()
        if failure:
            raise failure[0]

    def _read(self) -> Iterator[list[tuple[int, bytes]]]:
        batch: list[tuple[int, bytes]] = []
        size = 0
        lines = iter_lines(self.path, max_record_bytes=self.max_record_bytes)
        while True:
            try:
                item = next(lines)
            except StopIteration:
                break
            except InputError as exc:
                self.error = exc
                break
            self.last_line = item[0]
            batch.append(item)
            size += len(item[1])
            if len(batch) >= self.batch_lines or size >= self.batch_bytes:
                yield batch
                batch, size = [], 0
        if batch:
            yield batch
