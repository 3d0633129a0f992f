"""The episode viewer on a step whose thinking holds 10 MB (issue 25: such a step never
rendered). The page shows it cut at `dash.TEXT_CHARS` characters, says so, and its button
downloads it whole; the server holds the cut text only.

A server of its own on a one-step run of the kettle, in the browser group.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import polars as pl
import pytest

import vge_analytics as va
from tests.bounded import run_bounded
from tests.hostile.picture_inputs import picture_bench
from vge_analytics import dashboard as dash

from .conftest import ARTIFACTS
from .streamlit_browser import AppPage, served

pytestmark = pytest.mark.xdist_group("browser")

THINKING = "I look at the kettle. " * 480_000  # 10,560,000 characters
"""The long thinking of step 1 (step 0 thinks briefly)."""


@pytest.fixture(scope="module")
def long_out(tmp_path_factory) -> Path:
    root = picture_bench(tmp_path_factory.mktemp("long"), None)
    steps = [
        {"output": "Thinking: the power button.\nAction: Click(500, 500)"},
        {"output": f"Thinking: {THINKING}\nAction: Timed_wait()"},
    ]
    episode = {"episode_id": "e1", "steps": steps}
    (root / "run" / "episodes.jsonl").write_text(json.dumps(episode) + "\n")
    out = root / "out"
    done = run_bounded(
        [sys.executable, "-m", "vge_analytics.cli", "replay", str(root / "run"),
         "--bench", str(root / "bench"), "--out", str(out)],
        timeout=300.0,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    return out


@pytest.fixture(scope="module")
def long_server(long_out, tmp_path_factory):
    log = tmp_path_factory.mktemp("server") / "vge-app-long.log"
    with served(long_out, log=log) as server:
        yield server


def test_the_viewer_steps_hold_the_texts_cut(long_out):
    whole = len(THINKING.strip())  # 10,559,999 characters
    steps = dash.viewer_steps(long_out, "r", "e1")
    assert steps["thinking"][0] == "the power button."
    assert steps["thinking"][1] == THINKING.strip()[: dash.TEXT_CHARS] + dash.CUT
    assert steps["thinking_chars"].to_list() == [17, whole]
    # the other columns are the episode's steps as the tables hold them
    full = va.episode_steps(long_out, "r", "e1")
    assert steps.drop(dash.LONG_TEXTS, *map(dash.chars_column, dash.LONG_TEXTS)).equals(
        full.drop(dash.LONG_TEXTS)
    )
    first, second = steps.row(0, named=True), steps.row(1, named=True)
    assert dash.long_texts(first) == []
    response = len("Thinking: ") + len(THINKING) + len("\nAction: Timed_wait()")  # 10,560,031
    assert dash.long_texts(second) == [
        dash.LongText("thinking", "thinking", whole),
        dash.LongText("output", "response", response),
    ]
    assert dash.long_texts(second)[0].note == (
        "The thinking holds 10,559,999 characters; the first 20,000 are shown. The button "
        "below downloads it whole."
    )
    assert dash.step_text(long_out, "r", "e1", 1, "thinking") == THINKING.strip().encode()
    with pytest.raises(va.UnknownColumnError, match="not a free text of a step: 'goal_state'"):
        dash.step_text(long_out, "r", "e1", 1, "goal_state")
    with pytest.raises(va.UnknownRunError, match="no step 7 in episode 'e1' of run 'r'"):
        dash.step_text(long_out, "r", "e1", 7, "thinking")


def test_a_long_action_is_cut_in_the_step_text():
    row = {"step": 0, "action_raw": "x" * 30_000, "parse_ok": False, "parse_detail": "y" * 5,
           "truncated": True}  # fmt: skip
    text = dash.step_markdown(row, pl.DataFrame({"goal_index": []}))
    assert f"`{'x' * dash.TEXT_CHARS}{dash.CUT}`" in text and "x" * 20_001 not in text


def _rss(pid: int) -> int:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) * 1024
    raise AssertionError("no VmRSS")


def test_a_long_thinking_is_shown_cut_and_downloaded_whole(page, long_server, tmp_path):
    steps = dash.viewer_steps(long_server.out, "r", "e1")
    assert steps["thinking_chars"].to_list() == [len("the power button."), len(THINKING.strip())]
    browser = AppPage(page, long_server.url, timeout=120.0)
    browser.open("episode_viewer?run=r&episode=e1&step=0", "Step 0")
    before = _rss(long_server.pid)
    browser.open(
        "episode_viewer?run=r&episode=e1&step=1",
        f"The thinking holds {len(THINKING.strip()):,} characters; the first 20,000 are shown.",
    )
    assert not browser.errors(), browser.errors()
    shown = browser.text()
    assert THINKING[:2_000] in shown and THINKING[:25_000] not in shown
    assert "Download the whole response" in shown
    browser.screenshot(ARTIFACTS / "app-viewer-long-thinking.png")
    whole = browser.download("Download the whole thinking", tmp_path)
    assert whole.name == "r-e1-step1-thinking.txt"
    assert whole.read_text(encoding="utf-8") == THINKING.strip()
    assert _rss(long_server.pid) < before + 128 * 1024**2  # not a copy per rerun or session
    assert not browser.page_errors, browser.page_errors
