"""Writing one `.eval` log sample by sample: the zip file inspect_ai's own recorder writes,
member for member and byte for byte, written once.

A log is a zip file of JSON members, each compressed with Zstandard (compression method 93,
which inspect_ai reads and writes through `zipfile_zstd`): `_journal/start.json` (the
spec and plan), then the samples (`samples/<id>_epoch_<epoch>.json`) in groups of
`FLUSH_EVERY` (or fewer, once they hold `FLUSH_BYTES` characters of text and pictures), each
group followed by its summaries (`_journal/summaries/<n>.json`), and at the end every
summary (`summaries.json`) and the header with the results (`header.json`). That is the
layout of the recorder the eval itself uses (`inspect log convert --stream` too), flushed
as the export flushed it before: a reader sees the same log, and the same OUT gives the
same bytes as before.

The export holds one group of samples, encoded, and the summaries (encoded too: a few kB
each) until the log is finished; the log is written into a staged file that replaces the
destination when it is whole (`_export`). Each member is stamped 1980-01-01 00:00, the
earliest time a zip file can record (no clock is read). inspect_ai's recorder, finishing a
log, measures its members with `ZipInfo.FileHeader(zip64=True)`, which raises their
recorded versions to 4.5 (ZIP64) in the central directory; the members written before the
finish say so here too.
"""

from __future__ import annotations

import zipfile
import zlib
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import msgspec
import zstandard

from ._inspect import sample_summary

FLUSH_EVERY = 200
"""Samples held in memory before they are written to the log..."""
FLUSH_BYTES = 8 * 1024**2
"""... or fewer, once their text and pictures add up to this many characters."""
ZIP_EPOCH = (1980, 1, 1, 0, 0, 0)
"""The earliest time a zip file can record: every member's stamp."""
ZIP64_VERSION = 45
ZSTANDARD = 93
"""The zip compression method of Zstandard."""
ZSTD_LEVEL = 3
"""inspect_ai's (zipfile_zstd's default)."""

_ENCODER = msgspec.json.Encoder()
LARGE = 1e16
"""From here on msgspec writes a float as 1e16 where pydantic (inspect_ai's serializer)
writes 1e+16; it writes NaN and the infinities as null, pydantic as NaN and Infinity."""


def plain_numbers(values: Iterable[Any]) -> bool:
    """Whether `values` (strings, integers, floats, lists of strings or integers: a row of
    the replay's tables) hold no float msgspec writes otherwise than pydantic."""
    return all(type(v) is not float or -LARGE < v < LARGE for v in values)


def _plain(value: Any) -> bool:
    """`plain_numbers` for any JSON value, however nested (a header, a run's settings)."""
    if isinstance(value, dict):
        return all(_plain(v) for v in value.values())
    if isinstance(value, list | tuple):
        return all(_plain(v) for v in value)
    return type(value) is not float or -LARGE < value < LARGE


def _plain_sample(sample: dict[str, Any]) -> bool:
    """Where a sample's floats are: the episode's row, the steps' rows (on the answers),
    and what is derived from them (scores, usage: sums and ratios of those)."""
    return plain_numbers(sample["metadata"].values()) and all(
        plain_numbers(m["metadata"].values()) for m in sample["messages"] if "metadata" in m
    )


def to_json(value: Any, *, plain: bool | None = None, indent: int | None = None) -> bytes:
    """`value` as inspect_ai writes it (pydantic-core's JSON): msgspec's encoding, the same
    but for the floats `plain` says are absent (None: look); `indent`: pydantic's indented
    form, for the summaries' measures."""
    if indent is None and (plain if plain is not None else _plain(value)):
        try:
            return _ENCODER.encode(value)
        except UnicodeEncodeError:  # a lone surrogate: inspect_ai escapes it, as below
            pass
    import pydantic_core

    try:
        return pydantic_core.to_json(value, indent=indent)
    except pydantic_core.PydanticSerializationError:
        return pydantic_core.to_json(_clean(value), indent=indent)


def _clean(value: Any) -> Any:
    if isinstance(value, str):
        return value.encode("utf-8", errors="backslashreplace").decode("utf-8")
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_clean(v) for v in value]
    return value


def _indented(value: Any) -> bytes:
    return to_json(value, indent=2)


class _Log:
    """The zip file of one log, member by member."""

    def __init__(self, path: Path) -> None:
        self.zip = zipfile.ZipFile(path, "w")
        # one compressor for every member, each a frame of its own: the bytes
        # zipfile_zstd's compressor (level 3, threaded) gives, without its 12 threads
        # started for each member
        self.zstd = zstandard.ZstdCompressor(level=ZSTD_LEVEL, threads=1)
        self.summaries: list[bytes] = []
        self.groups = 0

    def member(self, name: str, data: bytes) -> None:
        """Write `data` as the member `name`: its local header (`ZipInfo.FileHeader`, what
        `ZipFile.writestr` writes), its compressed bytes, and its entry for the central
        directory, which `ZipFile.close` writes after the last member."""
        packer = self.zstd.compressobj()
        packed = packer.compress(data) + packer.flush()
        info = zipfile.ZipInfo(name, date_time=ZIP_EPOCH)
        info.compress_type = ZSTANDARD
        info.external_attr = 0o600 << 16  # what ZipFile.writestr gives a member named by str
        info.file_size, info.compress_size, info.CRC = len(data), len(packed), zlib.crc32(data)
        fh = self.zip.fp
        info.header_offset = fh.tell()
        fh.write(info.FileHeader(zip64=False))
        fh.write(packed)
        self.zip.filelist.append(info)
        self.zip.NameToInfo[name] = info
        self.zip.start_dir = fh.tell()  # where the central directory goes

    def group(self, samples: list[tuple[str, bytes, bytes]]) -> None:
        """Write a group of samples ((file name, JSON, summary's JSON)) and their summaries."""
        if not samples:
            return
        for name, data, _ in samples:
            self.member(name, data)
        self.groups += 1
        summaries = [summary for _, _, summary in samples]
        self.member(f"_journal/summaries/{self.groups}.json", _json_list(summaries))
        self.summaries.extend(summaries)

    def finish(self, header: bytes) -> None:
        for info in self.zip.infolist():
            info.create_version = max(info.create_version, ZIP64_VERSION)
            info.extract_version = max(info.extract_version, ZIP64_VERSION)
        self.member("summaries.json", _json_list(self.summaries))
        self.member("header.json", header)
        self.zip.close()


def _json_list(items: list[bytes]) -> bytes:
    return b"[" + b",".join(items) + b"]"


def write_eval(
    path: Path,
    start: dict[str, Any],
    samples: Iterable[tuple[dict[str, Any], int]],
    finish: Callable[[], dict[str, Any]],
) -> None:
    """Write the log at `path` from `start` (version, spec, plan) and `samples` ((sample,
    characters of its messages), consumed one at a time); `finish` gives the header once
    every sample is written."""
    log = _Log(path)
    try:
        log.member("_journal/start.json", to_json(start))
        held: list[tuple[str, bytes, bytes]] = []
        size = 0
        for sample, chars in samples:
            name = f"samples/{sample['id']}_epoch_{sample['epoch']}.json"
            plain = _plain_sample(sample)  # and so its summary, which holds less
            summary = sample_summary(sample, _indented)
            held.append((name, to_json(sample, plain=plain), to_json(summary, plain=plain)))
            size += chars
            if len(held) == FLUSH_EVERY or size >= FLUSH_BYTES:
                log.group(held)
                held, size = [], 0
        log.group(held)
        log.finish(to_json(finish()))
    except BaseException:
        log.zip.close()
        raise


__all__ = ["FLUSH_BYTES", "FLUSH_EVERY", "ZIP_EPOCH", "plain_numbers", "to_json", "write_eval"]
