"""Incremental replays (skip when inputs, options and engine are unchanged; `force`), and
atomic writes: an interrupted replay leaves no partial file visible to a reader."""

from __future__ import annotations

import hashlib
from pathlib import Path

import duckdb
import pytest

import replay
from replay.io import _batch

from ..conftest import Sample
from .conftest import fail_after


def _state(out: Path) -> dict[str, tuple[str, int]]:
    """sha256 and inode of every visible file (an untouched file keeps its inode)."""
    return {
        str(p.relative_to(out)): (hashlib.sha256(p.read_bytes()).hexdigest(), p.stat().st_ino)
        for p in sorted(out.rglob("*"))
        if p.is_file() and ".replay" not in p.parts
    }


def _visible_rows(out: Path) -> dict[str, int]:
    rows = duckdb.sql(
        f"SELECT run_id, count(*) FROM read_parquet('{out}/steps/**/*.parquet') GROUP BY 1"
    ).fetchall()
    return dict(rows)


def test_skip_then_force(copy_sample: Sample, tmp_path: Path) -> None:
    s, out = copy_sample, tmp_path / "out"
    first = replay.replay_runs(s.runs, s.bench, out, progress=False)
    before = _state(out)
    again = replay.replay_runs(s.runs, s.bench, out, progress=False)
    assert again.skipped == ["human-1", "vlm-a"] and again.replayed == []
    after = _state(out)
    tables = {k: v for k, v in before.items() if k.endswith(".parquet") and "runs/" not in k}
    assert all(after[k] == v for k, v in tables.items())  # not rewritten
    assert {k: v[0] for k, v in after.items()} == {k: v[0] for k, v in before.items()}
    assert again.content == first.content
    forced = replay.replay_runs(s.runs, s.bench, out, force=True, progress=False)
    assert forced.replayed == ["human-1", "vlm-a"] and forced.skipped == []
    assert {k: v[0] for k, v in _state(out).items()} == {k: v[0] for k, v in before.items()}


def test_changed_inputs_and_options_redo_only_those_runs(
    copy_sample: Sample, tmp_path: Path
) -> None:
    s, out = copy_sample, tmp_path / "out"
    replay.replay_runs(s.runs, s.bench, out, progress=False)
    # run.json of one run
    run_json = s.human / "run.json"
    run_json.write_text(run_json.read_text().replace('"humans"', '"people"'))
    m = replay.replay_runs(s.runs, s.bench, out, progress=False)
    assert m.replayed == ["human-1"] and m.skipped == ["vlm-a"]
    assert m.run("human-1").run.model == "people"
    # an SSM both runs use
    ssm = s.bench / "ssm" / "kettle.json"
    ssm.write_text(ssm.read_text() + "\n")
    m = replay.replay_runs(s.runs, s.bench, out, progress=False)
    assert m.replayed == ["human-1", "vlm-a"]
    # an option
    m = replay.replay_runs([s.vlm], s.bench, out, lam=3, progress=False)
    assert m.replayed == ["vlm-a"]
    m = replay.replay_runs([s.vlm], s.bench, out, lam=3, progress=False)
    assert m.skipped == ["vlm-a"]
    # the engine version
    manifest = (out / "manifest.json").read_text()
    (out / "manifest.json").write_text(
        manifest.replace('"engine_version": "', '"engine_version": "old-')
    )
    m = replay.replay_runs([s.vlm], s.bench, out, lam=3, progress=False)
    assert m.replayed == ["vlm-a"]


def test_other_runs_stay_complete(copy_sample: Sample, tmp_path: Path) -> None:
    """Replaying one run keeps the other runs' tables, quarantine and manifest entries."""
    s, out = copy_sample, tmp_path / "out"
    lines = (s.vlm / "episodes.jsonl").read_bytes()
    (s.vlm / "episodes.jsonl").write_bytes(lines + b"not json\n")
    replay.replay_runs(s.runs, s.bench, out, progress=False)
    quarantine = (out / "quarantine.jsonl").read_bytes()
    assert quarantine.count(b"\n") == 1
    m = replay.replay_runs([s.human], s.bench, out, force=True, progress=False)
    assert [r.run_id for r in m.runs] == ["human-1", "vlm-a"]
    assert m.exit_code == 0  # the quarantined record belongs to a run not asked for
    assert (out / "quarantine.jsonl").read_bytes() == quarantine
    assert set(_visible_rows(out)) == {"human-1", "vlm-a"}
    m = replay.replay_runs([s.vlm], s.bench, out, progress=False)
    assert m.skipped == ["vlm-a"] and m.exit_code == 2  # skipped runs still report


@pytest.mark.parametrize(
    ("target", "name", "n"),
    [
        (_batch, "replay_kernel", 2),  # mid-run, in the compiled replay
        (_batch, "replay_episode", 20),  # mid-run, in the reference replay loop
        (_batch, "write_part", 2),  # mid-run, while writing a Parquet part
    ],
)
def test_interrupted_replay_leaves_previous_output_intact(
    copy_sample: Sample,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    target: object,
    name: str,
    n: int,
) -> None:
    s, out = copy_sample, tmp_path / "out"
    if name == "replay_episode":
        monkeypatch.setattr("replay.io._batch.KERNEL", False)  # the reference engine
    monkeypatch.setattr("replay.io._job.BATCH_LINES", 4)
    monkeypatch.setattr("replay.io._files.ROW_GROUP_ROWS", 16)
    replay.replay_runs([s.vlm], s.bench, out, progress=False)
    before = _state(out)
    rows = _visible_rows(out)
    with monkeypatch.context() as patch:
        fail_after(patch, target, name, n)
        with pytest.raises(Exception, match="simulated crash"):
            replay.replay_runs([s.vlm, s.human], s.bench, out, force=True, progress=False)
    after = _state(out)
    # the run that failed keeps its previous, complete output; no temporary file is visible
    vlm_files = {k: v for k, v in before.items() if "vlm-a" in k}
    assert {k: v for k, v in after.items() if "vlm-a" in k} == vlm_files
    assert not [k for k in after if k.endswith(".tmp")]
    assert _visible_rows(out)["vlm-a"] == rows["vlm-a"]
    assert not (out / ".replay" / "staging").exists()
    # the next replay completes
    m = replay.replay_runs([s.vlm, s.human], s.bench, out, progress=False)
    assert m.exit_code == 0 and set(_visible_rows(out)) == {"human-1", "vlm-a"}
