"""Inflating with zlib-ng (`io/_lines.py`) reads every gzip input exactly as the standard
library's zlib does: the same lines, and the same error at the same place for a cut, a
corrupt, a padded or a concatenated stream."""

from __future__ import annotations

import gzip
import hashlib
import random
import zlib
from pathlib import Path

import pytest

from replay._errors import InputError
from replay.io import _lines


def _lines_of(seed: int, n: int) -> bytes:
    """Lines that compress little, so that a file spans several of the reader's 8 KiB reads."""
    rng = random.Random(seed)
    return b"".join(
        hashlib.sha256(f"{seed}-{i}".encode()).hexdigest().encode() * rng.randint(1, 6)
        + (b"\n\n" if i % 7 == 0 else b"\n")
        for i in range(n)
    )


def _stream() -> bytes:
    """Three members (one empty), the zero padding gzip allows between them."""
    return (
        gzip.compress(_lines_of(1, 300), mtime=0)
        + gzip.compress(b"", mtime=0)
        + b"\0" * 5
        + gzip.compress(_lines_of(2, 200), compresslevel=1, mtime=0)
    )


def _read(path: Path, engine, monkeypatch: pytest.MonkeyPatch, limit: int):
    """What `iter_lines` yields and the error that ends it, inflating with `engine`."""
    monkeypatch.setattr(_lines, "_zlib", engine)
    got: list[tuple[int, bytes]] = []
    try:
        got.extend(_lines.iter_lines(path, max_record_bytes=limit))
    except InputError as exc:
        return got, (type(exc).__name__, exc.message, exc.line)
    return got, None


def _same_as_zlib(path: Path, monkeypatch: pytest.MonkeyPatch, limit: int = 1 << 20):
    fast = _read(path, _lines._FAST_ZLIB, monkeypatch, limit)
    assert fast == _read(path, zlib, monkeypatch, limit)
    return fast


def test_the_fast_engine_is_zlib_ng() -> None:
    """Installed with the package (pyproject.toml), so the tests below compare two engines."""
    assert _lines._FAST_ZLIB.__name__ == "zlib_ng.zlib_ng"


def test_whole_streams_read_the_same(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "e.jsonl.gz"
    data = _stream()
    path.write_bytes(data)
    lines, error = _same_as_zlib(path, monkeypatch)
    expected = (_lines_of(1, 300) + _lines_of(2, 200)).split(b"\n")
    assert [raw for _, raw in lines] == [x for x in expected if x]
    assert lines[-1][0] == len(expected) - 1 and error is None
    # a line over the bound, found in the second member
    lines, error = _same_as_zlib(path, monkeypatch, limit=300)
    assert error is not None and error[0] == "RecordTooLarge"
    # garbage after the last member
    path.write_bytes(data + b"garbage")
    lines, error = _same_as_zlib(path, monkeypatch)
    assert len(lines) == 500 and error == (
        "InputError",
        "unreadable (Not a gzipped file (b'ga'))",
        None,
    )


def test_cut_streams_read_the_same(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    data = _stream()
    path = tmp_path / "e.jsonl.gz"
    kinds = set()
    for cut in range(7, len(data), 397):
        path.write_bytes(data[:cut])
        lines, error = _same_as_zlib(path, monkeypatch)
        kinds.add(error[1] if error else None)
    assert "unreadable (Compressed file ended before the end-of-stream marker was reached)" in kinds


def test_corrupt_streams_read_the_same(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A byte changed anywhere (a header, the deflate data, a CRC, a length): the same lines
    before the same error."""
    data = _stream()
    path = tmp_path / "e.jsonl.gz"
    rng = random.Random(0)
    kinds = set()
    for at in [*range(0, 24), *rng.sample(range(len(data)), 150), *range(len(data) - 24, len(data))]:
        corrupt = bytearray(data)
        corrupt[at] ^= 1 << rng.randrange(8)
        path.write_bytes(bytes(corrupt))
        lines, error = _same_as_zlib(path, monkeypatch)
        kinds.add(error[1].split(" ")[1] if error else None)
    assert {"(CRC", "(Error"} <= kinds


def test_read_whole_reads_the_same(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "s.json.gz"
    path.write_bytes(_stream())
    whole = {}
    for engine in (_lines._FAST_ZLIB, zlib):
        monkeypatch.setattr(_lines, "_zlib", engine)
        whole[engine] = _lines.read_whole(_lines_location(path))
    assert whole[zlib] == whole[_lines._FAST_ZLIB] == _lines_of(1, 300) + _lines_of(2, 200)


def _lines_location(path: Path):
    from replay.io._fs import location

    return location(str(path))
