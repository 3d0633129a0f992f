"""The export writes Inspect logs itself (`export/_inspect.py`, `_inspect_log.py`): here
inspect_ai's own recorder, given the log's spec, plan, samples and results as its models
read them back, writes the same log again, member for member (names, order, bytes,
compression method, recorded versions); only the members' time stamps differ (the
recorder's are the clock's). What the recorder makes itself, the samples' summaries and the
header, is thus checked against inspect_ai's rules (thinning, field order, defaults)."""

from __future__ import annotations

import asyncio
import json
import zipfile
from pathlib import Path

import pytest
from inspect_ai.log import condense_sample, read_eval_log
from inspect_ai.log._recorders import create_recorder_for_location

from vge_analytics.export import export
from vge_analytics.export._inspect_log import to_json


def _groups(path: Path) -> list[int]:
    """How many samples each journal of summaries holds: where the log was flushed."""
    with zipfile.ZipFile(path) as zf:
        journals = sorted(
            (n for n in zf.namelist() if n.startswith("_journal/summaries/")),
            key=lambda n: int(n.rsplit("/", 1)[1].split(".")[0]),
        )
        return [len(json.loads(zf.read(n))) for n in journals]


def _rewrite(path: Path, dest: Path, condense: bool) -> None:
    """`path` written again by inspect_ai's recorder, flushed where the export flushed;
    `condense`: each sample through `condense_sample`, as `write_eval_log` does a sample
    with pictures (a sample read back has them as attachments already)."""
    log = read_eval_log(path)
    log.eval.dataset.sample_ids = None  # the reader lists them; a log written by an eval
    # (or by the export) does not
    samples = iter(log.samples)

    async def run() -> None:
        recorder = create_recorder_for_location(str(dest), str(dest.parent))
        await recorder.log_init(log.eval, str(dest), clean=True)
        await recorder.log_start(log.eval, log.plan)
        (zipped,) = recorder.data.values()
        for size in _groups(path):
            for _ in range(size):
                sample = next(samples)
                await recorder.log_sample(log.eval, condense_sample(sample) if condense else sample)
            await zipped.write_buffered_samples()
        await recorder.log_finish(log.eval, "success", log.stats, log.results, None)

    asyncio.run(run())


def _members(path: Path) -> list[tuple]:
    with zipfile.ZipFile(path) as zf:
        return [
            (i.filename, i.compress_type, i.create_version, i.extract_version, zf.read(i))
            for i in zf.infolist()
        ]


@pytest.mark.parametrize("images", ["embed", "none", "usage"])
def test_inspects_recorder_writes_the_same_log(
    hand_out, hand_inspect, out_with_usage, tmp_path, images
):
    """The hand-worked runs with pictures, without, and with the usage a harness records
    (tokens, latency, cost on the kettle run's steps: the samples' and the run's usage)."""
    if images == "embed":
        dest = hand_inspect[0]
    else:
        dest = tmp_path / images
        export(out_with_usage if images == "usage" else hand_out, "inspect", dest, images="none")
    logs = sorted(dest.glob("*.eval"))
    assert [p.name for p in logs] == ["kettle-vlm.eval", "oven-human.eval"]
    for path in logs:
        again = tmp_path / f"again-{images}-{path.name}"
        _rewrite(path, again, condense=images == "embed")
        ours, theirs = _members(path), _members(again)
        assert [m[:4] for m in ours] == [m[:4] for m in theirs]
        for mine, recorded in zip(ours, theirs, strict=True):
            assert mine[4] == recorded[4], mine[0]
        names = [m[0] for m in ours]
        assert names[0] == "_journal/start.json" and names[-2:] == ["summaries.json", "header.json"]
    kettle = _members(dest / "kettle-vlm.eval")
    with_pictures = [m for m in kettle if m[0].startswith("samples/") and b"attachment://" in m[4]]
    assert len(with_pictures) == (7 if images == "embed" else 0)
    if images == "usage":
        header = json.loads(dict((m[0], m[4]) for m in kettle)["header.json"])
        assert header["stats"]["model_usage"]["model-k"]["input_tokens"] > 0


def test_floats_msgspec_writes_otherwise_go_through_pydantic():
    """msgspec writes 1e16 and NaN as `1e16` and `null`; inspect_ai (pydantic) as `1e+16`
    and `NaN`: such a value is encoded as inspect_ai does."""
    value = {"a": [1.5, 2], "b": 1e16, "c": "x"}
    assert to_json(value) == b'{"a":[1.5,2],"b":1e+16,"c":"x"}'
    assert to_json({"n": float("nan")}) == b'{"n":NaN}'
    assert to_json({"a": 0.1, "b": [1, "2"]}) == b'{"a":0.1,"b":[1,"2"]}'
    assert to_json({"s": "\ud800"}) == b'{"s":"\\\\ud800"}'
