"""MCAP files read back with the `mcap` reader: channels, schemas, counts, timestamps."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pyarrow.parquet as pq
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from foxglove_schemas_protobuf.ImageAnnotations_pb2 import ImageAnnotations
from foxglove_schemas_protobuf.Log_pb2 import Log
from mcap.reader import make_reader

import replay
from replay.io import safe_file_name

from ..conftest import IMAGE_SIZE, Sample

SCHEMAS = {
    "/camera": "foxglove.CompressedImage",
    "/annotations": "foxglove.ImageAnnotations",
    "/model": "foxglove.Log",
    "/feedback": "foxglove.Log",
    "/step": "vge.StepRow",
}


def _read(path: Path) -> dict:
    with open(path, "rb") as fh:
        reader = make_reader(fh)
        summary = reader.get_summary()
        assert summary is not None
        channels = {c.id: c for c in summary.channels.values()}
        schemas = {s.id: s for s in summary.schemas.values()}
        messages: dict[str, list] = {}
        for schema, channel, message in reader.iter_messages():
            messages.setdefault(channel.topic, []).append((schema, message))
        attachments = list(reader.iter_attachments())
        metadata = list(reader.iter_metadata())
    return {
        "channels": {
            c.topic: (schemas[c.schema_id].name, c.message_encoding) for c in channels.values()
        },
        "messages": messages,
        "attachments": attachments,
        "metadata": metadata,
    }


def _ns(stamp) -> int:
    return stamp.seconds * 1_000_000_000 + stamp.nanos


def test_every_episode_file(replayed, sample: Sample) -> None:
    out, manifest = replayed
    steps = pq.read_table(out / "steps", partitioning=None).to_pylist()
    by_episode: dict[tuple[str, str], list[dict]] = {}
    for row in steps:
        by_episode.setdefault((row["run_id"], row["episode_id"]), []).append(row)
    files = sorted((out / "mcap").rglob("*.mcap"))
    assert len(files) == len(by_episode) == sum(e.counts.mcap_files for e in manifest.runs)
    with_camera = 0
    for (run_id, episode_id), rows in sorted(by_episode.items()):
        path = out / "mcap" / run_id / f"{safe_file_name(episode_id)}.mcap"
        got = _read(path)
        kettle = rows[0]["device_id"] == "kettle"
        scored = [r for r in rows if not r["truncated"]]
        # channels and schema names
        want = {t: s for t, s in SCHEMAS.items() if kettle or t != "/camera"}
        if not scored:
            want.pop("/annotations")
            want.pop("/feedback")
        assert {t: name for t, (name, _) in got["channels"].items()} == want
        assert got["channels"]["/step"][1] == "json"
        assert got["channels"]["/model"][1] == "protobuf"
        # message counts
        msgs = got["messages"]
        assert len(msgs["/step"]) == len(msgs["/model"]) == len(rows)
        assert len(msgs.get("/annotations", [])) == len(msgs.get("/feedback", [])) == len(scored)
        views = [rows[0]["view_before"] or "front"] + [r["view_before"] for r in scored]
        changes = 1 + sum(a != b for a, b in zip(views[1:], views[2:], strict=False))
        assert len(msgs.get("/camera", [])) == (changes if kettle else 0)
        # step records, model text, feedback levels
        records = [json.loads(m.data) for _, m in msgs["/step"]]
        assert [r["step"] for r in records] == [r["step"] for r in rows]
        assert records == rows
        feedback = [Log.FromString(m.data) for _, m in msgs.get("/feedback", [])]
        assert [f.name for f in feedback] == [r["feedback_kind"] for r in scored]
        assert all(f.level in (Log.INFO, Log.WARNING, Log.ERROR) for f in feedback)
        # timestamps: recorded, else step i at i seconds
        times = [m.log_time for _, m in msgs["/step"]]
        if episode_id.endswith("-c2"):
            assert times == [round((1_700_000_000 + 2.5 * i) * 1e9) for i in range(len(rows))]
        else:
            assert times == [i * 1_000_000_000 for i in range(len(rows))]
        # annotations carry the timestamp of the image they are drawn on
        cameras = [
            (m.log_time, CompressedImage.FromString(m.data)) for _, m in msgs.get("/camera", [])
        ]
        camera_stamps = {_ns(img.timestamp) for _, img in cameras}
        for _, m in msgs.get("/annotations", []):
            ann = ImageAnnotations.FromString(m.data)
            shown = max((t for t, _ in cameras if t <= m.log_time), default=None)
            if kettle:
                assert _ns(ann.timestamp) == shown
                assert _ns(ann.timestamp) in camera_stamps
            for p in ann.points:
                assert all(0 <= q.x <= (IMAGE_SIZE[0] if kettle else 1000) for q in p.points)
        for log_time, img in cameras:
            assert _ns(img.timestamp) == log_time and img.format == "png" and img.data
            with_camera += 1
        # attachment and metadata
        (attachment,) = got["attachments"]
        assert attachment.name == f"{rows[0]['device_id']}.ssm.json"
        assert json.loads(attachment.data)["states"]
        (meta,) = got["metadata"]
        assert meta.name == "episode" and meta.metadata["episode_id"] == episode_id
    assert with_camera > 0


def test_click_and_boxes_in_image_pixels(replayed, sample: Sample) -> None:
    """A kettle step with a click: the circle sits at x * W / 1000, y * H / 1000."""
    out, _ = replayed
    steps = pq.read_table(out / "steps" / "run_id=vlm-a", partitioning=None).to_pylist()
    row = next(
        r for r in steps if r["device_id"] == "kettle" and r["x"] is not None and r["hit_target"]
    )
    got = _read(out / "mcap" / "vlm-a" / f"{safe_file_name(row['episode_id'])}.mcap")
    ann = [ImageAnnotations.FromString(m.data) for _, m in got["messages"]["/annotations"]][
        row["step"]
    ]
    (circle,) = ann.circles
    assert circle.position.x == row["x"] * IMAGE_SIZE[0] / 1000
    assert circle.position.y == row["y"] * IMAGE_SIZE[1] / 1000
    labels = [t.text for t in ann.texts]
    assert any(label.startswith("target: ") for label in labels)
    assert set(row["hit_components"]) <= {label.removeprefix("target: ") for label in labels}


def test_mcap_episodes_limits_files(sample: Sample, tmp_path: Path) -> None:
    wanted = [sample.episode_ids[0], sample.episode_ids[5]]
    m = replay.replay_runs(
        [sample.vlm], sample.bench, tmp_path, mcap_episodes=wanted, progress=False
    )
    files = sorted(p.name for p in (tmp_path / "mcap" / "vlm-a").iterdir())
    assert files == sorted(f"{safe_file_name(e)}.mcap" for e in wanted)
    assert m.run("vlm-a").options.mcap is True
    assert m.run("vlm-a").counts.mcap_files == 2
    # without --mcap the run's MCAP directory goes away on the next replay
    replay.replay_runs([sample.vlm], sample.bench, tmp_path, progress=False)
    assert not (tmp_path / "mcap" / "vlm-a").exists()


def test_the_files_from_the_kernels_rows_are_the_references(
    sample: Sample, tmp_path: Path, monkeypatch
) -> None:
    """Every MCAP file of the sample, written from the kernel's rows read back three
    episodes at a time, is byte for byte the file the reference's own rows give (the runner
    with `VGE_REPLAY_ENGINE=reference` writes from them)."""
    images = replay.BenchImages(str(sample.bench))
    monkeypatch.setattr("replay.io._batch.MCAP_ROWS_AT_ONCE", 3)
    replay.replay_runs(
        sample.runs, sample.bench, tmp_path / "kernel", mcap=True, progress=False,
        image_source=images,
    )  # fmt: skip
    monkeypatch.setattr("replay.io._batch.KERNEL", False)
    replay.replay_runs(
        sample.runs, sample.bench, tmp_path / "reference", mcap=True, progress=False,
        image_source=images,
    )  # fmt: skip
    kernel = sorted((tmp_path / "kernel" / "mcap").rglob("*.mcap"))
    reference = sorted((tmp_path / "reference" / "mcap").rglob("*.mcap"))
    names = [p.relative_to(tmp_path / "kernel") for p in kernel]
    assert names == [p.relative_to(tmp_path / "reference") for p in reference]
    assert len(kernel) > 2 * 3  # several reads of three episodes in a run
    for a, b in zip(kernel, reference, strict=True):
        assert a.read_bytes() == b.read_bytes(), a.name


MCAP_LIBRARIES = ("mcap", "mcap_protobuf", "foxglove_schemas_protobuf", "google.protobuf")
_PROBE = """
import json, sys
import replay
replay.replay_runs([sys.argv[1]], sys.argv[2], sys.argv[3], mcap=sys.argv[4] == "1",
                   progress=False, force=True)
libs = {libs!r}
print(json.dumps(sorted({{x for m in sys.modules for x in libs if m == x or m.startswith(x + ".")}})))
"""


def _libraries_after_replay(sample: Sample, out: Path, mcap: bool) -> list[str]:
    """The MCAP libraries a fresh interpreter has imported after replaying the vlm run."""
    done = subprocess.run(
        [
            sys.executable, "-c", _PROBE.format(libs=MCAP_LIBRARIES),
            str(sample.vlm), str(sample.bench), str(out), "1" if mcap else "0",
        ],
        capture_output=True, text=True, timeout=300, check=True,
    )  # fmt: skip
    return json.loads(done.stdout.splitlines()[-1])


def test_a_replay_without_mcap_loads_no_mcap_library(sample: Sample, tmp_path: Path) -> None:
    # Each worker process would pay for them (docs/PERFORMANCE.md, "Replay, whole process").
    assert _libraries_after_replay(sample, tmp_path / "plain", mcap=False) == []
    # The same probe sees them once an MCAP file is written.
    assert _libraries_after_replay(sample, tmp_path / "mcap", mcap=True) == sorted(MCAP_LIBRARIES)


_BATCH_PROBE = """
import gzip, json, os, sys
from replay.io import episodes_file
from replay.io._batch import BatchTask, RunContext, replay_batch
path = episodes_file(sys.argv[1]).local
raw = gzip.decompress(path.read_bytes()) if path.suffix == ".gz" else path.read_bytes()
lines = tuple((i + 1, line) for i, line in enumerate(raw.splitlines()) if line.strip())
ctx = RunContext("r", "m", "vlm", None, None, str(path), sys.argv[3], 65_536)
for table in ("steps", "episodes", "goals"):
    os.makedirs(os.path.join(sys.argv[3], table))
report = replay_batch(BatchTask(ctx, sys.argv[2], 0, lines))
print(json.dumps([report.parts["steps"], "pandas" in sys.modules, "pyarrow.compute" in sys.modules]))
"""


def test_a_replayed_batch_imports_no_pandas(sample: Sample, tmp_path: Path) -> None:
    """A worker replays and writes its batches without pandas (0.26 s of CPU to import, in
    each worker process): its columns are made from buffers, not with `pa.array`; nor
    `pyarrow.compute` (0.03 s), whose functions its counts call by name."""
    done = subprocess.run(
        [sys.executable, "-c", _BATCH_PROBE, str(sample.vlm), str(sample.bench), str(tmp_path)],
        capture_output=True, text=True, timeout=300, check=True,
    )  # fmt: skip
    steps, pandas, compute = json.loads(done.stdout.splitlines()[-1])
    assert steps > 0
    assert not pandas
    assert not compute
