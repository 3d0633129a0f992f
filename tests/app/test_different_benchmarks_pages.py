"""The pages that compare runs (Significance, Side by side) over an OUT holding runs of two
benchmarks: each says in one line which runs differ and why, instead of comparing episodes
that share ids, not tasks (issue 25)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

import replay
import vge_analytics as va

from .test_pages import open_page

LOGS = Path(__file__).resolve().parents[2] / "logs"


@pytest.fixture(scope="module")
def two_benchmarks(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("two")
    other = root / "bench2"
    shutil.copytree(LOGS / "bench", other)
    tasks = other / "tasks.jsonl"
    tasks.write_text(tasks.read_text().replace("Choose 200 degrees", "Set 200 degrees", 1))
    out = root / "out"
    for run, bench in (("sim-vlm-a", LOGS / "bench"), ("sim-vlm-b", other)):
        replay.replay_runs([str(LOGS / "runs" / run)], str(bench), str(out), progress=False)
    return out


@pytest.mark.parametrize("page", ["significance", "side_by_side"])
def test_a_comparing_page_names_the_runs_of_two_benchmarks(two_benchmarks, monkeypatch, page):
    monkeypatch.setenv("VGE_APP_OUT", str(two_benchmarks))
    at = open_page(page)
    pair = ["sim-vlm-a", "sim-vlm-b"]  # Significance: every run, in order
    if page == "side_by_side":  # the runs the page picked
        pair = [at.selectbox(key="sbs_a").value, at.selectbox(key="sbs_b").value]
    with pytest.raises(va.DifferentBenchmarksError) as caught:
        va.diff(two_benchmarks, *pair)
    assert [e.value for e in at.main.error] == [str(caught.value)]
    assert str(caught.value).startswith(
        f"runs {pair[0]!r} and {pair[1]!r} of {two_benchmarks} were replayed against "
        "different benchmarks ("
    )
    assert not at.dataframe  # nothing compared
