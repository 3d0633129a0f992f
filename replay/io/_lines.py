"""Reading input files within the bound on a record (PROTOCOL §1.5): the lines of a
`.jsonl` or `.jsonl.gz` file, in blocks and in linear time, and a whole file (an SSM,
run.json). Nothing longer than the bound is held, and a file that never ends is read for at
most that many bytes past its last record."""

from __future__ import annotations

import gzip
import io
import zlib
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, BinaryIO

from .._errors import InputError, RecordTooLarge

if TYPE_CHECKING:
    from ._fs import Location

MAX_RECORD_BYTES = 64 << 20
"""The default maximum size of a record (PROTOCOL §1.5): a line of an episodes file or of
tasks.jsonl, a whole SSM or run.json."""


def read_whole(path: Location, limit: int = MAX_RECORD_BYTES) -> bytes:
    """A whole file (inflated if `.gz`), refused past `limit` bytes without reading more."""
    gz = path.suffix == ".gz"
    try:
        with path.open_read() as raw, _gunzip(raw) if gz else raw as fh:
            data = fh.read(limit + 1)
    except FileNotFoundError:
        raise InputError(str(path), "file not found") from None
    except (gzip.BadGzipFile, EOFError, *_ZLIB_ERRORS) as exc:
        raise InputError(str(path), f"not a valid gzip file: {exc}") from None
    except OSError as exc:
        raise InputError(str(path), f"cannot read: {exc.strerror or exc}") from None
    if len(data) > limit:
        raise RecordTooLarge(
            str(path), f"larger than {limit:,} bytes, the maximum size of a record"
        )
    return data


def iter_lines(
    path: str | Path | Location, *, max_record_bytes: int = MAX_RECORD_BYTES
) -> Iterator[tuple[int, bytes]]:
    """(line number from 1, raw line) of a .jsonl or .jsonl.gz file, blank lines skipped.

    What cannot be read ends the file with an `InputError`, raised once every complete line
    before it was yielded: a truncated or corrupt gzip stream, an I/O error, or
    (`RecordTooLarge`) a line or a run of blank lines longer than `max_record_bytes`, so
    that a file which never ends, or inflates without end, is read for at most that many
    bytes past its last record (PROTOCOL §1.5). Read in blocks (`read1`: one read of the
    underlying stream each, so a failing read loses nothing already decompressed) and split
    in bulk, several times faster than line by line through `gzip`.
    """
    from ._fs import location  # pyarrow's file systems: imported when a file is read

    path = location(path)
    lines = _Lines(str(path), max_record_bytes)
    try:
        with path.open_read() as raw:
            read = _Inflater(raw).read if path.suffix == ".gz" else raw.read1
            while block := read(_BLOCK):
                yield from lines.split(block)
        yield from lines.end()
    except FileNotFoundError:
        raise InputError(str(path), "file not found") from None
    except (OSError, EOFError, *_ZLIB_ERRORS) as exc:
        raise InputError(str(path), f"unreadable ({exc})") from None


_BLOCK = 1 << 20


class _Lines:
    """Numbered non-blank lines of a stream of blocks, each line joined once (linear time).

    The bound on a record (PROTOCOL §1.5): a line longer than `limit`, blank or not, is too
    large at its own number (found as soon as its start passes `limit`, so it is never held
    whole); a run of blank lines longer than `limit` is too large at its first line."""

    def __init__(self, path: str, limit: int) -> None:
        self.path = path
        self.limit = limit
        self.number = 0  # lines ended so far
        self.head: list[bytes] = []  # the current line so far, when no block held its end
        self.head_bytes = 0
        self.blank_from = 0  # first line of the current run of blank lines
        self.blank_bytes = 0  # bytes of that run (newlines included); 0: no run

    def split(self, block: bytes) -> Iterator[tuple[int, bytes]]:
        pieces = block.split(b"\n")
        tail = pieces.pop()
        if pieces and not self._blank_block(block, pieces, len(block) - len(tail)):
            yield from self._ended(pieces)
        if tail:
            self.head.append(tail)
            self.head_bytes += len(tail)
            self._check_line(self.head_bytes, self.number + 1)

    def _ended(self, pieces: list[bytes]) -> Iterator[tuple[int, bytes]]:
        """The lines a block ends, the first one joined to what came before it."""
        if self.head:
            self._check_line(self.head_bytes + len(pieces[0]), self.number + 1)
            pieces[0] = b"".join([*self.head, pieces[0]])
            self.head, self.head_bytes = [], 0
        limit = self.limit
        for raw in pieces:
            self.number += 1
            if len(raw) > limit:
                self._check_line(len(raw), self.number)
            line = raw.strip()
            if line:
                self.blank_bytes = 0
                yield self.number, line
            else:
                if not self.blank_bytes:
                    self.blank_from = self.number
                self.blank_bytes += len(raw) + 1
                self._check_blank()

    def _blank_block(self, block: bytes, pieces: list[bytes], ended: int) -> bool:
        """Take the lines of a block that only ends blank lines in one step (a file of
        blank lines is read as fast as any other); False when the line-by-line loop must
        decide (a record, or a bound passed: that loop finds where)."""
        if not block.isspace() or any(not piece.isspace() for piece in self.head):
            return False
        longest = max(self.head_bytes + len(pieces[0]), max(map(len, pieces)))
        size = self.head_bytes + ended  # the lines it ends, newlines included
        if longest > self.limit or self.blank_bytes + size > self.limit:
            return False
        if not self.blank_bytes:
            self.blank_from = self.number + 1
        self.blank_bytes += size
        self.number += len(pieces)
        self.head, self.head_bytes = [], 0
        return True

    def end(self) -> Iterator[tuple[int, bytes]]:
        """The last line, when the stream does not end with a newline."""
        if self.head:
            line = b"".join(self.head).strip()
            self.head, self.head_bytes = [], 0
            if line:
                yield self.number + 1, line

    def _check_line(self, size: int, number: int) -> None:
        if size > self.limit:
            raise RecordTooLarge(
                self.path,
                f"line longer than {self.limit:,} bytes, the maximum size of a record "
                "(--max-record-bytes): it and the rest of the file are not read",
                number,
            )

    def _check_blank(self) -> None:
        if self.blank_bytes > self.limit:
            raise RecordTooLarge(
                self.path,
                f"more than {self.limit:,} bytes of blank lines, the maximum size of a "
                "record (--max-record-bytes): the rest of the file is not read",
                self.blank_from,
            )


try:  # zlib-ng: zlib's inflate and messages, 2.5 times faster here (docs/PERFORMANCE.md)
    from zlib_ng import zlib_ng as _FAST_ZLIB
except ImportError:  # pragma: no cover - a declared dependency; zlib gives the same bytes
    _FAST_ZLIB = zlib  # type: ignore[misc]
_zlib = _FAST_ZLIB
_ZLIB_ERRORS = (zlib.error, _FAST_ZLIB.error)


class _Inflater(gzip._GzipReader):  # type: ignore[name-defined,misc]
    """The standard library's gzip reader (its members, headers, CRC and length checks,
    messages and reads of the stream) with inflating and the CRC done by `_zlib`: the same
    bytes, blocks and errors as `gzip.GzipFile`, whose inflating and CRC were a third of
    reading a file. `read(n)`: at most n bytes, inflated from one read of the stream (so a
    failing read loses nothing already inflated), b"" at the end."""

    def __init__(self, fp: BinaryIO) -> None:
        super().__init__(fp)
        # the factory this Python's reader uses (zlib.decompressobj, or _ZlibDecompressor
        # from 3.12), taken from `_zlib` under the same name
        factory: Callable[..., object] = getattr(_zlib, self._decomp_factory.__name__)
        self._decomp_factory = factory
        self._decompressor = factory(**self._decomp_args)

    def _add_read_data(self, data: bytes) -> None:
        self._crc = _zlib.crc32(data, self._crc)
        self._stream_size = self._stream_size + len(data)


def _gunzip(raw: BinaryIO) -> BinaryIO:
    """A whole file's reader, with `_Inflater`'s inflating."""
    return io.BufferedReader(_Inflater(raw))  # type: ignore[return-value]


__all__ = ["MAX_RECORD_BYTES", "iter_lines", "read_whole"]
