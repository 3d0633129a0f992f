"""`vge diff` over an OUT in object storage (an S3-compatible server on 127.0.0.1): it reads
through the store, so the rows and the printed output are those of the local copy."""

from __future__ import annotations

from pathlib import Path

import pytest

import replay
import vge_analytics as va
from vge_analytics.cli import main

from ..conftest import Sample


def test_diff_reads_an_out_in_s3(
    s3_server, sample: Sample, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    fs, query = s3_server
    local = tmp_path / "local"
    out = f"s3://vge/diff?{query}"
    for target in (local, out):
        replay.replay_runs(sample.runs, sample.bench, target, progress=False)
    human, vlm = va.runs(local)["run_id"].to_list()
    want = va.diff(local, human, vlm)
    # The human run played a third of the episodes, every one of which the VLM run played.
    assert want.episodes.height == va.episodes(local, where={"run_id": human}).height > 0
    assert va.diff(out, human, vlm).rows.equals(want.rows)
    capsys.readouterr()
    assert main(["diff", out, human, vlm, "-f", "csv"]) == 0
    remote = capsys.readouterr().out
    assert main(["diff", str(local), human, vlm, "-f", "csv"]) == 0
    assert remote == capsys.readouterr().out and "median_first_difference" in remote
