"""End to end: the Side by side page in Chromium (the session's `app_server` on the tiny
benchmark). Two runs and an episode chosen by the URL, the step moved with the keyboard and
with a mark's button, both pictures drawn, the marks shown as `vge diff` computes them; then
the way a person gets there: a flipped episode on Human vs VLM, and its link."""

from __future__ import annotations

import time

import polars as pl

import vge_analytics as va
from vge_analytics import dashboard as dash

from .conftest import ARTIFACTS
from .streamlit_browser import AppPage

_PICTURES_JS = """() => Array.from(document.querySelectorAll('[data-testid="stImage"] img'))
  .filter(i => i.complete && i.naturalWidth > 0).length"""


def pictures(browser: AppPage) -> int:
    """Pictures the page shows, loaded."""
    return int(browser.page.evaluate(_PICTURES_JS))


def act(browser: AppPage, action, expect: str) -> None:
    """Do something that reruns the page, and wait until that rerun shows `expect`."""
    before = browser.run_number()
    started = time.monotonic()
    action()
    browser.wait_rendered(expect, started, after=before)


def test_side_by_side_in_chromium(app_page: AppPage, tiny_out):
    rows = dash.pair_rows(tiny_out, "sim-vlm-a", "sim-vlm-f")
    row = rows.filter(
        pl.col("first_difference") > 0,
        pl.col("first_difference") < pl.min_horizontal("steps_a", "steps_b"),  # both go on
        pl.col("first_error_a").is_not_null(),
        pl.col("first_error_b").is_not_null(),
    ).row(0, named=True)
    episode, k = row["episode_id"], row["first_difference"]
    browser = app_page
    browser.open(f"side_by_side?a=sim-vlm-a&b=sim-vlm-f&episode={episode}&step=0", "Run B")
    assert not browser.errors(), browser.errors()
    text = browser.text()
    assert f"First difference step {k}" in text
    assert f"A's first error step {row['first_error_a']}" in text
    assert pictures(browser) == 2
    # A caption per run. At step 0 each run is at the task's start, from which the replay
    # planned the task (PROTOCOL §4.3), so the planner's next step exists: never "no optimal
    # next step" there. The two runs start alike; their captions differ in what they did.
    for run in ("sim-vlm-a", "sim-vlm-f"):
        optimal = dash.side_picture(tiny_out, run, episode, 0).optimal
        assert optimal is not None
        step_row = dash.side_steps(tiny_out, run, episode).row(0, named=True)
        assert dash.side_caption(step_row, optimal) in text
    assert "no optimal next step" not in text

    # The keyboard moves the shared slider: both sides show step 1.
    slider = browser.page.get_by_role("slider").first
    act(browser, lambda: (slider.focus(), slider.press("ArrowRight")), "step 1 of")
    assert browser.page.url.endswith(f"episode={episode}&step=1")
    assert browser.text().count("step 1 of") == 2

    # The mark's button jumps to the first difference; the slider's thumb names it.
    button = browser.page.locator("button", has_text=f"Step {k}: first difference").first
    act(browser, button.click, f"step {k} of")
    assert browser.page.url.endswith(f"&step={k}")
    assert f"{k} · first difference" in browser.text()
    assert pictures(browser) == 2
    browser.screenshot(ARTIFACTS / "app-side-by-side.png", full_page=True)
    assert not browser.errors(), browser.errors()

    # From Human vs VLM: the first flipped episode, both runs side by side.
    browser.navigate("/human_vs_vlm", "Episodes that flip")
    human = "sim-human"
    model = dash.run_choices(va.runs(tiny_out))[1][0]  # the page's default: the best model
    flips = va.compare(tiny_out, model, human).flips
    first = flips["episode_id"][0]
    browser.select_first_row()
    address = browser.follow_link(f"Side by side: {first}", "Run B")
    assert f"/side_by_side?a={human}&b={model}&episode={first}&step=0" in address
    assert pictures(browser) == 2  # both runs played the episode: each has a step 0
    summary = dash.pair_summary(
        dash.pair_rows(tiny_out, human, model)
        .filter(pl.col("episode_id") == first)
        .row(0, named=True)
    )
    assert summary.replace("**", "") in browser.text()
    assert not browser.errors() and not browser.page_errors, browser.page_errors
