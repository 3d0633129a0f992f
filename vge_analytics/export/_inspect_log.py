"""Writing one `.eval` log sample by sample, with `inspect_ai`'s own recorder.

`inspect_ai.log.write_eval_log` takes a whole `EvalLog`, every sample in memory; a run of
the full benchmark has 15,000 episodes. The eval itself writes its log with a recorder,
one sample at a time (`log_init`, `log_start`, `log_sample`, `flush`, `log_finish`; the
recorder that `inspect log convert --stream` also uses), so the export does the same: it
holds at most `FLUSH_EVERY` samples (or `FLUSH_BYTES` of them) before they go to the
recorder's temporary file, and the
log appears at its destination, whole, when it is finished. The recorder lives in a private
module of inspect_ai, hence the pinned version of the `export` extra.

Samples with pictures go through `condense_sample` (as `write_eval_log` does), which stores
each distinct picture once per sample as an attachment. Without pictures there is nothing
for it to do, and it is skipped: it is the most expensive step of writing a sample.

The recorder stamps each zip member with the time it was written. Those stamps are the only
bytes of the file that would vary from one export to the next, so once the log is finished
they are set to the earliest time a zip file can hold (1980-01-01 00:00), in place: the same
OUT gives a byte-identical log.
"""

from __future__ import annotations

import asyncio
import struct
import zipfile
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import anyio
from inspect_ai.log import EvalPlan, EvalResults, EvalSample, EvalSpec, EvalStats, condense_sample
from inspect_ai.log._recorders import Recorder, create_recorder_for_location

FLUSH_EVERY = 200
"""Samples held in memory before they are written to the recorder's temporary file..."""
FLUSH_BYTES = 8 * 1024**2
"""... or fewer, once their text and pictures add up to this many characters."""

ZIP_EPOCH = (0, (1 << 5) | 1)
"""DOS time and date fields of 1980-01-01 00:00:00, the earliest a zip file can record."""


def write_eval(
    path: Path,
    spec: EvalSpec,
    plan: EvalPlan,
    samples: Iterable[EvalSample],
    finish: Callable[[], tuple[EvalResults, EvalStats]],
    *,
    condense: bool,
) -> None:
    """Write the log at `path` from `samples` (consumed one at a time); `finish` gives the
    results and stats once every sample is written."""

    async def run() -> None:
        recorder = create_recorder_for_location(str(path), str(path.parent))
        await recorder.log_init(spec, str(path), clean=True)
        await recorder.log_start(spec, plan)
        held = count = 0
        for sample in samples:
            await recorder.log_sample(spec, condense_sample(sample) if condense else sample)
            count, held = count + 1, held + _size(sample)
            if count == FLUSH_EVERY or held >= FLUSH_BYTES:
                await _write_buffered(recorder, spec)
                held = count = 0
        results, stats = finish()
        await recorder.log_finish(spec, "success", stats, results, None)

    try:
        asyncio.get_running_loop()
    except RuntimeError:
        anyio.run(run)
    else:  # called from a running event loop (a notebook, Playwright's sync API): no second
        # loop can run in this thread, so the recorder gets a thread of its own
        with ThreadPoolExecutor(1) as pool:
            pool.submit(anyio.run, run).result()
    fix_zip_times(path)


def _size(sample: EvalSample) -> int:
    """The characters of a sample's messages, text and pictures (data URLs): what it holds."""
    size = 0
    for message in sample.messages:
        if isinstance(message.content, str):
            size += len(message.content)
            continue
        for part in message.content:
            size += len(getattr(part, "text", "") or getattr(part, "image", "") or "")
    return size


async def _write_buffered(recorder: Recorder, spec: EvalSpec) -> None:
    """Move the buffered samples into the recorder's temporary zip file. `recorder.flush`
    does that and then copies the whole file written so far to its destination: on a run of
    15,000 samples that is gigabytes of copies, quadratic in the run. The recorder's zip file
    (`EvalRecorder.data`, one per eval) writes its buffer alone; the destination is written
    once, by `log_finish`. Should a later inspect_ai arrange its recorder otherwise, `flush`
    does the same work, slower."""
    files = getattr(recorder, "data", None)
    if isinstance(files, dict) and len(files) == 1:
        (log,) = files.values()
        if hasattr(log, "write_buffered_samples"):
            await log.write_buffered_samples()
            return
    await recorder.flush(spec)


def fix_zip_times(path: Path) -> None:
    """Set the modification time of every member of the zip file at `path` to ZIP_EPOCH, in
    its local header and in the central directory (nothing else changes: the stamps are in
    no checksum)."""
    with zipfile.ZipFile(path) as zf:
        members = zf.infolist()
        central = zf.start_dir
    stamp = struct.pack("<HH", *ZIP_EPOCH)
    with path.open("r+b") as fh:
        for info in members:
            fh.seek(info.header_offset)
            if fh.read(4) != b"PK\x03\x04":
                raise ValueError(f"{path}: not a local file header at {info.header_offset}")
            fh.seek(info.header_offset + 10)
            fh.write(stamp)
        offset = central
        for _ in members:
            fh.seek(offset)
            head = fh.read(46)
            if head[:4] != b"PK\x01\x02":
                raise ValueError(f"{path}: not a central directory entry at {offset}")
            fh.seek(offset + 12)
            fh.write(stamp)
            name, extra, comment = struct.unpack("<HHH", head[28:34])
            offset += 46 + name + extra + comment


__all__ = ["FLUSH_BYTES", "FLUSH_EVERY", "ZIP_EPOCH", "fix_zip_times", "write_eval"]
