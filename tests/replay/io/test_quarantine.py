"""Nothing lost: bad records are quarantined with file, line, kind and reason; the rest
replays; counts add up; `vge replay` exits 2 (quarantine) or 1 (fatal, one line)."""

from __future__ import annotations

import gzip
import json
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
import pytest

import replay

from ..conftest import Sample, write_lines


def _broken_copy(s: Sample) -> tuple[list[tuple[int, str | None, str]], int]:
    """Rewrite the vlm run with one bad record of each kind; returns the expected
    quarantine (line, episode_id, kind) and the number of good lines."""
    good = (s.vlm / "episodes.jsonl").read_bytes().splitlines()
    first_id = json.loads(good[0])["episode_id"]
    third_id = json.loads(good[2])["episode_id"]
    lines: list[bytes] = []
    expected: list[tuple[int, str | None, str]] = []

    def bad(line: bytes, episode_id: str | None, kind: str) -> None:
        lines.append(line)
        expected.append((len(lines), episode_id, kind))

    lines += good[:3]
    bad(good[3][: len(good[3]) // 2], None, "malformed_json")  # truncated line
    bad(b'{"episode_id": "x", "steps": [}', None, "malformed_json")
    lines += good[3:6]
    bad(b'{"episode_id": "ghost-device", "steps": []}', "ghost-device", "unknown_device")
    bad(b'{"episode_id": "no-such-episode", "steps": []}', "no-such-episode", "unknown_episode")
    bad(b'{"episode_id": 17, "steps": []}', None, "invalid_record")
    bad(b'{"episode_id": "y", "steps": "none"}', "y", "invalid_record")
    bad(
        json.dumps({"episode_id": first_id, "steps": [{"output": "x"}, 3]}).encode(),
        first_id,
        "step_not_object",
    )
    lines.append(b"   ")  # blank lines are not records
    bad(good[0], first_id, "duplicate_episode")
    bad(b'{"episode_id": "bad-task", "steps": []}', "bad-task", "task_error")
    lines += good[6:]
    bad(good[2], third_id, "duplicate_episode")
    write_lines(s.vlm / "episodes.jsonl", lines)
    return expected, len(good)


def test_broken_run_quarantines_exactly_the_bad_records(
    vge, copy_sample: Sample, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    s = copy_sample
    expected, n_good = _broken_copy(s)
    out = tmp_path / "out"
    code = vge(["replay", str(s.vlm), "--bench", str(s.bench), "--out", str(out)])
    assert code == 2
    assert "quarantine.jsonl" in capsys.readouterr().out

    records = [json.loads(line) for line in (out / "quarantine.jsonl").read_text().splitlines()]
    assert [(r["line"], r["episode_id"], r["kind"]) for r in records] == expected
    for r in records:
        assert r["run_id"] == "vlm-a"
        assert r["file"] == str(s.vlm / "episodes.jsonl")
        assert r["reason"] and "\n" not in r["reason"]
        assert r["kind"] in replay.QUARANTINE_KINDS
    by_line = {r["line"]: r for r in records}
    step_bad = next(r for r in records if r["kind"] == "step_not_object")
    assert step_bad["reason"] == "step 1 is not an object (got int)"
    dup = [r for r in records if r["kind"] == "duplicate_episode"]
    assert "line 1" in dup[0]["reason"]
    assert "toaster" in by_line[expected[2][0]]["reason"]

    manifest = replay.read_manifest(out)
    assert manifest is not None
    entry = manifest.runs[0]
    c = entry.counts
    assert c.replayed == n_good
    assert c.quarantined == len(expected)
    assert c.lines_read == c.replayed + c.quarantined
    kinds: dict[str, int] = {}
    for _, _, kind in expected:
        kinds[kind] = kinds.get(kind, 0) + 1
    assert entry.quarantine == dict(sorted(kinds.items()))
    episodes = pq.read_table(out / "episodes", partitioning=None)
    ids = episodes["episode_id"].to_pylist()
    assert len(ids) == len(set(ids)) == n_good  # the duplicates' rows are not kept
    assert set(ids) == set(s.episode_ids)
    steps = pq.read_table(out / "steps", partitioning=None)
    assert steps.num_rows == c.steps == sum(s.steps_per_episode.values())


def test_duplicates_across_batches(
    copy_sample: Sample, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Duplicates are decided in the main process, whatever the batch they fall in."""
    s = copy_sample
    expected, n_good = _broken_copy(s)
    monkeypatch.setattr("replay.io._job.BATCH_LINES", 4)
    small = replay.replay_runs([s.vlm], s.bench, tmp_path / "small", progress=False)
    monkeypatch.setattr("replay.io._job.BATCH_LINES", 1000)
    one = replay.replay_runs([s.vlm], s.bench, tmp_path / "one", progress=False)
    assert small.exit_code == one.exit_code == 2
    quarantine = [(tmp_path / d / "quarantine.jsonl").read_bytes() for d in ("small", "one")]
    assert quarantine[0] == quarantine[1]
    # Same counts and the same rows (a duplicate in a later batch made that batch be
    # replayed again without it); only the cut into parts differs.
    assert small.run("vlm-a").counts == one.run("vlm-a").counts
    for table in ("steps", "episodes", "goals"):
        rows = [
            pa.concat_tables(
                pq.read_table(p) for p in sorted((tmp_path / d / table).glob("*/*.parquet"))
            )
            for d in ("small", "one")
        ]
        assert rows[0].equals(rows[1])
    assert one.run("vlm-a").counts.replayed == n_good
    assert one.run("vlm-a").quarantine["duplicate_episode"] == 2


def test_truncated_gzip(copy_sample: Sample, tmp_path: Path) -> None:
    """A gzip stream cut in the middle: what can be read is replayed, the tail is one
    `truncated_file` record."""
    s = copy_sample
    path = s.human / "episodes.jsonl.gz"
    block = gzip.decompress(path.read_bytes())
    n_lines = len(block.splitlines())
    data = gzip.compress(block * 40, mtime=0)  # long enough to cut in the middle
    path.write_bytes(data[: len(data) * 2 // 3])
    m = replay.replay_runs([s.human], s.bench, tmp_path / "out", progress=False)
    c = m.run("human-1").counts
    text = (tmp_path / "out" / "quarantine.jsonl").read_text()
    records = [json.loads(x) for x in text.splitlines()]
    tail = [r for r in records if r["kind"] == "truncated_file"]
    assert len(tail) == 1 and tail[0] == records[-1]
    assert {r["kind"] for r in records[:-1]} == {"duplicate_episode"}  # the repeated blocks
    assert c.replayed == n_lines
    assert c.lines_read == c.replayed + c.quarantined
    assert tail[0]["line"] == c.lines_read  # the unreadable tail counts as one line read
    assert "cannot be read from line" in tail[0]["reason"]
    assert m.exit_code == 2


def test_fatal_errors_are_one_line(
    vge, sample: Sample, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad_run = tmp_path / "badrun"
    bad_run.mkdir()
    (bad_run / "run.json").write_text('{"run_id": "x", "model": 3}')
    (bad_run / "episodes.jsonl").write_text("")
    cases = [
        ([str(bad_run)], str(sample.bench), str(bad_run / "run.json")),
        ([str(sample.vlm)], str(tmp_path / "nobench"), str(tmp_path / "nobench")),
        ([str(tmp_path / "norun")], str(sample.bench), str(tmp_path / "norun")),
        ([str(sample.vlm), str(sample.vlm)], str(sample.bench), "vlm-a"),
    ]
    for runs, bench, named in cases:
        code = vge(["replay", *runs, "--bench", bench, "--out", str(tmp_path / "out")])
        err = capsys.readouterr().err
        assert code == 1, err
        assert err.count("\n") == 1 and named in err and "Traceback" not in err


def test_clean_run_exits_zero(
    vge, sample: Sample, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["replay", str(sample.human), "--bench", str(sample.bench), "--out", str(tmp_path)]
    assert vge([*argv, "--no-progress"]) == 0
    printed = capsys.readouterr().out
    assert "quarantine.jsonl" not in printed
    # The human run holds each of the 13 hand-worked cases once (conftest): 80 logged steps
    # (the 12 cases of test_metrics_hand.py have 77, the overlap case 3), 4 truncated
    # (kettle b's and d's 2 each), 22 goals (kettle 13, oven 8, overlap 1), nothing recorded
    # to diverge and nothing quarantined: an empty quarantine file.
    (entry,) = replay.read_manifest(tmp_path).runs
    c = entry.counts
    assert (c.lines_read, c.replayed, c.quarantined, c.steps) == (13, 13, 0, 80)
    assert (c.truncated_steps, c.diverged_steps, c.goals, c.mcap_files) == (4, 0, 22, 0)
    assert entry.quarantine == {} and (tmp_path / "quarantine.jsonl").read_bytes() == b""
    ids = pq.read_table(tmp_path / "episodes", partitioning=None)["episode_id"].to_pylist()
    assert sorted(ids) == sorted(sample.episode_ids[:13])
