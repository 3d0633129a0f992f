"""The bundled sample (`logs/`, written by `vge synth --scale sample`): it replays with
nothing quarantined, identically with 1 and 2 workers; a broken copy quarantines exactly
the broken records."""

from __future__ import annotations

import gzip
import hashlib
import json
import shutil
from pathlib import Path

import pyarrow.parquet as pq
import pytest

import replay
from vge_analytics.synth import image_source

LOGS = Path(__file__).resolve().parents[3] / "logs"
RUNS = sorted(p for p in (LOGS / "runs").iterdir() if p.is_dir())


@pytest.fixture(scope="module")
def logs_replayed(tmp_path_factory: pytest.TempPathFactory):
    out = tmp_path_factory.mktemp("logs") / "out"
    return out, replay.replay_runs(RUNS, LOGS / "bench", out, progress=False)


def test_sample_replays_with_nothing_quarantined(logs_replayed) -> None:
    out, manifest = logs_replayed
    assert len(RUNS) >= 2
    assert manifest.exit_code == 0
    assert (out / "quarantine.jsonl").read_bytes() == b""
    for entry in manifest.runs:
        c = entry.counts
        assert c.quarantined == 0 and c.lines_read == c.replayed > 0, entry.run_id
        with gzip.open(entry.inputs.episodes.path) as fh:
            assert c.lines_read == sum(1 for line in fh if line.strip())
        steps = pq.read_table(out / "steps" / f"run_id={entry.run_id}", partitioning=None)
        assert steps.num_rows == c.steps
        d = entry.divergence
        assert d.steps_diverged == sum(x is True for x in steps["diverged"].to_pylist())
        assert d.steps_compared == steps.num_rows - steps["diverged"].null_count


def test_sample_identical_with_two_workers(logs_replayed, tmp_path: Path) -> None:
    """Parquet, quarantine and manifest byte-identical with 1 and 2 workers (MCAP of a few
    episodes, with the CLI's rendered views, compared too)."""
    out, _ = logs_replayed
    runs = RUNS[:2]
    first = _first_ids(runs[0], 2)
    outs = []
    for name, workers in (("w1", 1), ("w2", 2)):
        target = tmp_path / name
        replay.replay_runs(
            runs,
            LOGS / "bench",
            target,
            workers=workers,
            mcap_episodes=first,
            progress=False,
            image_source=image_source(LOGS / "bench"),
        )
        outs.append(_digests(target))
    assert outs[0] == outs[1]
    assert sum(k.endswith(".mcap") for k in outs[0]) == 2 * len(runs)
    for k, digest in outs[0].items():  # same rows as the full replay of every run
        if k.endswith(".parquet") and k.startswith("steps/"):
            assert digest == _digests(out)[k]


def test_broken_copy_of_the_sample(vge, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bench = tmp_path / "bench"
    shutil.copytree(LOGS / "bench", bench)
    run = tmp_path / RUNS[0].name
    shutil.copytree(RUNS[0], run)
    path = replay.episodes_file(run)
    good = gzip.decompress(path.read_bytes()).splitlines()
    tasks = (bench / "tasks.jsonl").read_bytes().splitlines()
    moved = json.loads(good[1])["episode_id"]
    for i, line in enumerate(tasks):  # the task of episode 2 now names a device with no SSM
        task = json.loads(line)
        if task["episode_id"] == moved:
            tasks[i] = json.dumps({**task, "device_id": "NoSuchDevice_000"}).encode()
    (bench / "tasks.jsonl").write_bytes(b"\n".join(tasks) + b"\n")
    lines = [
        good[0],
        good[1],  # line 2: unknown device
        good[2][:-40],  # line 3: truncated
        b"{not json",  # line 4
        json.dumps({"episode_id": 12, "steps": []}).encode(),  # line 5: wrong types
        *good[3:],
    ]
    path.write_bytes(gzip.compress(b"\n".join(lines) + b"\n", mtime=0))
    out = tmp_path / "out"
    assert vge(["replay", str(run), "--bench", str(bench), "--out", str(out)]) == 2
    capsys.readouterr()
    records = [json.loads(x) for x in (out / "quarantine.jsonl").read_text().splitlines()]
    assert [(r["line"], r["kind"]) for r in records] == [
        (2, "unknown_device"),
        (3, "malformed_json"),
        (4, "malformed_json"),
        (5, "invalid_record"),
    ]
    manifest = replay.read_manifest(out)
    assert manifest is not None
    c = manifest.runs[0].counts
    assert c.replayed == len(good) - 2 and c.quarantined == 4
    assert c.lines_read == c.replayed + c.quarantined == len(lines)


def _first_ids(run: Path, n: int) -> list[str]:
    with gzip.open(replay.episodes_file(run)) as fh:
        return [json.loads(next(fh))["episode_id"] for _ in range(n)]


def _digests(out: Path) -> dict[str, str]:
    return {
        str(p.relative_to(out)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(out.rglob("*"))
        if p.is_file() and ".replay" not in p.parts
    }


def test_run_header_bytes_writes_run_json_as_the_sample_has_it() -> None:
    # A document's keys in the order given: the sample's run.json files, byte for byte.
    for run in RUNS:
        data = (run / "run.json").read_bytes()
        assert replay.io.run_header_bytes(json.loads(data)) == data, run.name
    # A RunHeader: its fields in their declared order, its meta's keys sorted.
    header = replay.RunHeader(run_id="r", model="m", agent_kind="human", meta={"b": 1, "a": 0.5})
    assert replay.io.run_header_bytes(header) == (
        b'{\n  "run_id": "r",\n  "model": "m",\n  "agent_kind": "human",\n  "lambda": null,\n'
        b'  "meta": {\n    "a": 0.5,\n    "b": 1\n  },\n  "schema_version": 1\n}\n'
    )
