"""A batch in a worker process: an episode whose checks passed is kept ready for its next
lines (bounded); one that failed a check is checked, and reported, again at each line."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from replay.io._batch import BatchReport, BatchTask, LineOutcome, RunContext, replay_batch
from replay.io._worker import worker_state

from ..conftest import Sample

BAD = [
    b'{"episode_id": "ghost-device", "steps": []}',
    b'{"episode_id": "bad-task", "steps": []}',
    b'{"episode_id": "no-such-episode", "steps": []}',
]


def _lines(s: Sample) -> tuple[tuple[int, bytes], ...]:
    """Two good episodes around the three bad ones, on lines 1, 3, 4, 6 and 7 (2 and 5 are
    blank lines, not given to a batch)."""
    good = (s.vlm / "episodes.jsonl").read_bytes().splitlines()[:2]
    return ((1, good[0]), (3, BAD[0]), (4, BAD[1]), (6, BAD[2]), (7, good[1]))


def _replay(s: Sample, staging: Path, index: int) -> BatchReport:
    ctx = RunContext("r", "m", "vlm", None, None, "episodes.jsonl", str(staging), 65_536)
    for table in ("steps", "episodes", "goals"):
        (staging / table).mkdir(parents=True, exist_ok=True)
    report = replay_batch(BatchTask(ctx, str(s.bench), index, _lines(s)))
    assert isinstance(report, BatchReport)
    return report


def test_failed_checks_are_reported_at_every_line(copy_sample: Sample, tmp_path: Path) -> None:
    s = copy_sample
    first = _replay(s, tmp_path / "staging", 0)
    again = _replay(s, tmp_path / "staging", 1)  # same process: the good two are ready
    ids = s.episode_ids[:2]
    assert set(worker_state(str(s.bench)).ready) == set(ids)
    for report in (first, again):
        assert report.lines == 5
        assert report.episode_ids == [ids[0], "ghost-device", "bad-task", "no-such-episode", ids[1]]
        assert report.episode_lines == [1, 3, 4, 6, 7]
        assert [(o.line, o.episode_id, o.kind) for o in report.others] == [
            (3, "ghost-device", "unknown_device"),
            (4, "bad-task", "task_error"),
            (6, "no-such-episode", "unknown_episode"),
        ]
        assert report.parts["episodes"] == 2
    assert again.others == first.others  # the same reasons, word for word
    assert again.counts == first.counts
    tasks = [json.loads(t) for t in (s.bench / "tasks.jsonl").read_text().splitlines()]
    devices = {t["device_id"] for t in tasks if t["episode_id"] in (*ids, "bad-task")}
    assert first.devices == sorted(devices | {"toaster"})  # ghost-device's, without an SSM


def test_the_ready_episodes_are_bounded(
    copy_sample: Sample, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    s = copy_sample
    monkeypatch.setattr("replay.io._worker.SETUP_CACHE_SIZE", 1)
    first = _replay(s, tmp_path / "staging", 0)
    assert list(worker_state(str(s.bench)).ready) == [s.episode_ids[1]]  # the latest only
    again = _replay(s, tmp_path / "staging", 1)
    assert list(worker_state(str(s.bench)).ready) == [s.episode_ids[1]]
    assert (again.others, again.counts, again.parts) == (first.others, first.counts, first.parts)


def test_a_skipped_line_is_not_decoded(copy_sample: Sample, tmp_path: Path) -> None:
    s = copy_sample
    ctx = RunContext("r", "m", "vlm", None, None, "x", str(tmp_path), 65_536)
    for table in ("steps", "episodes", "goals"):
        (tmp_path / table).mkdir()
    task = BatchTask(ctx, str(s.bench), 0, _lines(s)).skipping(frozenset({1, 4}))
    report = replay_batch(task)
    assert isinstance(report, BatchReport)
    assert report.episode_lines == [3, 6, 7]
    assert report.others == [
        LineOutcome(1, None, "skipped", None),
        report.others[1],
        LineOutcome(4, None, "skipped", None),
        report.others[3],
    ]
    assert [o.kind for o in report.others] == [
        "skipped",
        "unknown_device",
        "skipped",
        "unknown_episode",
    ]
    assert report.lines - len(report.others) == report.parts["episodes"] == 1
