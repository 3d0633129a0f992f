"""End to end: Inspect's own viewer opens an exported log. Three episodes of a run of the
bundled sample are exported with their pictures, `inspect view start --log-dir DIR` runs as a
user starts it (on 127.0.0.1, a free port), and Debian's Chromium (Playwright, launched as the
dashboard's browser tests launch it: tests/app/conftest.py) opens one sample: its input and scores, its messages and
the pictures beside them. The screenshot goes to `tests/_artifacts/` (docs/EXPORT.md shows
it)."""

from __future__ import annotations

import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import pytest

import vge_analytics as va
from tests.app.streamlit_browser import free_port
from vge_analytics.export import export

ARTIFACTS = Path(__file__).resolve().parents[2] / "_artifacts"
STARTUP = 300.0
"""Seconds `inspect view` may take to answer (it imports the whole of inspect_ai: seconds on
an idle machine, a minute and more on a busy one). A wait, not a measure."""
WAIT_MS = 180_000
"""How long the page may take to show each thing the test waits for (Playwright's default,
30 s, is too short for a busy machine). A wait, not a measure."""

_IMAGES_JS = """() => Array.from(document.images)
  .filter(i => i.src.startsWith('data:image/jpeg'))
  .map(i => [i.complete, i.naturalWidth, i.naturalHeight])"""


RUN = "sim-vlm-f"


@pytest.fixture(scope="module")
def shown(sample_out) -> dict:
    """The episode the test opens: the run's first Microwave episode (a sample of three)."""
    rows = va.episodes(sample_out, where={"run_id": RUN, "category": "Microwave"}).to_dicts()
    return rows[0] | {"others": [r["episode_id"] for r in rows[1:3]]}


@pytest.fixture
def inspect_view(sample_out, shown, tmp_path):
    """`inspect view start` on the exported log; yields its address."""
    dest = tmp_path / "logs"
    episodes = [shown["episode_id"], *shown["others"]]
    export(sample_out, "inspect", dest, runs=[RUN], episodes=episodes, images="embed")
    port = free_port()
    log = tmp_path / "inspect-view.log"
    cmd = [sys.executable, "-m", "inspect_ai", "view", "start", "--log-dir", str(dest)]
    with log.open("wb") as sink:
        proc = subprocess.Popen(
            [*cmd, "--host", "127.0.0.1", "--port", str(port)], stdout=sink, stderr=sink
        )
    url = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + STARTUP
        while True:
            try:
                with urllib.request.urlopen(url, timeout=2) as answer:
                    if answer.status == 200:
                        break
            except OSError:
                pass
            assert proc.poll() is None and time.monotonic() < deadline, log.read_text()
            time.sleep(0.25)
        yield url
    finally:
        proc.terminate()
        proc.wait(timeout=20)


def test_inspect_view_shows_a_sample_with_its_pictures(page, inspect_view, sample_out, shown):
    episode = shown["episode_id"]
    (instruction,) = va.goals(sample_out, where={"run_id": RUN, "episode_id": episode})[
        "instruction"
    ]
    steps = va.episode_steps(sample_out, RUN, episode)
    page.set_default_timeout(WAIT_MS)
    page.goto(inspect_view)  # one log in the folder: the viewer opens it, listing its samples
    for other in shown["others"]:
        page.get_by_text(other, exact=True).first.wait_for()
    page.get_by_text(episode, exact=True).first.click()
    # the sample: its input, its scores, the conversation with the views
    page.get_by_text(f"Request: {instruction}").first.wait_for()
    page.get_by_text("goals_completed").first.wait_for()
    page.get_by_text("more...").nth(1).click()  # the first user message, picture unfolded
    page.wait_for_function(
        f"() => ({_IMAGES_JS})().length > 0 && ({_IMAGES_JS})().every(i => i[0])"
    )
    pictures = page.evaluate(_IMAGES_JS)
    assert pictures and all(max(w, h) == 512 for _, w, h in pictures), pictures
    text = page.inner_text("body")
    assert steps["thinking"][0] in text  # the first answer
    assert f"What happened: {steps['feedback_text'][0]}" in text  # and what it was told
    ARTIFACTS.mkdir(exist_ok=True)
    page.screenshot(path=str(ARTIFACTS / "export-inspect-view.png"))
