"""End to end: `vge app` serves the dashboard, headless Chromium (Playwright) loads every page.

The server is the `app_server` fixture (`vge app OUT --headless --port <free port>`, as a
user starts it); each page is loaded in Debian's Chromium, its rendered text and table cells
are checked against the analytics API, and a screenshot per page goes to `tests/_artifacts/`
(gitignored).
"""

from __future__ import annotations

import polars as pl
import pytest

import vge_analytics as va
from vge_analytics import dashboard as dash

from .conftest import ARTIFACTS


def cells_by_first_column(table: list[list[str]]) -> dict[str, dict[str, str]]:
    header, *rows = table
    return {row[0]: dict(zip(header, row, strict=False)) for row in rows}


def test_every_page_renders_in_chromium(app_page, tiny_out, tmp_path):
    metrics = va.metrics(tiny_out)
    runs = metrics["run_id"].to_list()
    episodes = va.episodes(tiny_out, where={"run_id": "sim-vlm-f"})
    episode = episodes.filter(pl.col("L_act") > 2)["episode_id"][0]
    steps = va.episode_steps(tiny_out, "sim-vlm-f", episode)
    first_view = dash.interaction_views(tiny_out).row(0, named=True)
    clicks = dash.click_points(tiny_out, first_view["device_id"], first_view["view"]).height
    invalid_coord = va.steps_with_error(tiny_out, "invalid_coord").height

    pages = [
        ("leaderboard", "", "Per metric"),
        ("errors", "errors", f"{invalid_coord} steps with Invalid Coord Error"),
        ("navigation", "navigation", "NP found the target"),
        ("grounding", "grounding", f"{clicks} clicks ("),
        ("budgets", "budgets", "SR gain over λ = 2"),
        ("human_vs_vlm", "human_vs_vlm", "common episodes"),
        (
            "episode_viewer",
            f"episode_viewer?run=sim-vlm-f&episode={episode}&step=2",
            "Download episode as MCAP",
        ),
        ("sql", "sql", "rows"),
    ]
    browser = app_page
    timings = {}
    for name, path, expect in pages:
        timings[name] = browser.open(path, expect)
        browser.screenshot(ARTIFACTS / f"app-{name}.png")
        text = browser.text()
        assert not browser.errors(), (name, browser.errors())
        assert "Traceback" not in text and "Error:" not in text, name
        assert "OUT" in text and str(tiny_out) in text, name  # the sidebar indicator
        if name == "leaderboard":
            shown = cells_by_first_column(browser.tables()[0])
            assert list(shown) == runs
            for row in metrics.iter_rows(named=True):
                assert float(shown[row["run_id"]]["SR ↑"]) == pytest.approx(row["SR"])
        if name == "episode_viewer":
            assert "Step 2" in text and steps["action_raw"][2] in text
            mcap = browser.download("Download episode as MCAP", tmp_path / "downloads")
            assert mcap.name == f"sim-vlm-f-{episode}.mcap"
            assert mcap.read_bytes() == dash.episode_mcap(tiny_out, "sim-vlm-f", episode)
        if name == "human_vs_vlm":
            table = cells_by_first_column(browser.tables()[0])
            assert set(table) >= {"SR ↑", "EIR ↑", "AvgDist ↓"}
    # The drill-down chain: error type -> its steps -> the episode viewer at that step.
    browser.open("errors", "Drill down")
    first = dash.error_step_sample(tiny_out, "invalid_coord", limit=1)[0].row(0, named=True)
    browser.select_first_row()
    address = browser.follow_link(f"Open {first['episode_id']}", "Download episode as MCAP")
    assert address.endswith(
        f"/episode_viewer?run={first['run_id']}&episode={first['episode_id']}&step={first['step']}"
    )
    assert f"Step {first['step']}" in browser.text()

    # Moving around by the sidebar, as a person does (same session, no reload).
    browser.navigate("/navigation", "NP found the target")
    assert not browser.errors()
    assert cells_by_first_column(browser.tables()[0]).keys() == set(runs)
    assert not browser.page_errors, browser.page_errors
    print("page load + render seconds:", {k: round(v, 2) for k, v in timings.items()})
