"""The Play page in Chromium: `vge play` as a real server, a person's clicks on the view.

Two clicks on the image (a view shown 480 pixels wide; the environment renders it 768
pixels square) become two steps whose 0..1000 coordinates are worked out here by hand; the
person then gives up, and the human run replays with zero divergent steps. A server killed
in the middle of an episode loses none of its steps: the next one offers to resume it.
"""

from __future__ import annotations

import json
import time

import replay
import vge_analytics as va

from .conftest import ARTIFACTS
from .streamlit_browser import AppPage, AppServer

IMAGE = 'iframe[title="streamlit_image_coordinates.streamlit_image_coordinates"]'
WIDTH = 480
"""`vge play --image-width 480` (the `play_server` fixture)."""


def journal_steps(run) -> list[dict]:
    (path,) = (run / "playing").glob("*.jsonl")
    return [json.loads(line) for line in path.read_text().splitlines()[1:]]


def click_image(browser: AppPage, x: int, y: int, expect: str) -> float:
    """Click the view at pixel (x, y) from its top-left corner; wait for the step. Returns
    the seconds from the click to the page showing it."""
    image = browser.page.frame_locator(IMAGE).locator("#image")
    image.wait_for()
    shown = image.evaluate("i => [i.complete && i.naturalWidth, i.width, i.height]")
    assert shown == [768, WIDTH, WIDTH], shown
    before = browser.run_number()
    started = time.monotonic()
    image.click(position={"x": x, "y": y})
    return browser.wait_rendered(expect, started, after=before)


def choose(browser: AppPage, option: str, expect: str) -> None:
    """Pick an option of the radio group (what a click does)."""
    before = browser.run_number()
    started = time.monotonic()
    browser.page.locator('[data-testid="stRadio"] label', has_text=option).click()
    browser.wait_rendered(expect, started, after=before)


def test_two_clicks_become_two_steps_and_the_run_replays(play_server, page, tmp_path):
    browser = AppPage(page, play_server.server.url)
    timings = {"open": browser.open("", "Goal 1 of 1")}
    text = browser.text()
    # The next episode not played: the first task, shown from its initial view.
    picked = browser.page.get_by_role("combobox", name="Episode").input_value()
    assert picked == "ElectricKettle_000-00 · ElectricKettle_000 · 1 goal"
    assert "Not played in this run yet." in text
    assert "The front_top view" in text
    assert "0 of 24 episodes played" in text

    # Click 1: switch to the front view, at pixel (120, 360) of the 480-pixel image:
    # 1000 * 120 / 480 = 250, 1000 * 360 / 480 = 750.
    choose(browser, "Switch_view", "View to switch to")
    timings["click 1"] = click_image(browser, 120, 360, "Step 0:")
    assert "The front view" in browser.text()
    # Click 2: press at pixel (301, 7): 1000 * 301 / 480 = 627.08 -> 627,
    # 1000 * 7 / 480 = 14.58 -> 15.
    choose(browser, "Press", "Click on it to press there")
    timings["click 2"] = click_image(browser, 301, 7, "Unfinished: 2 steps played so far.")
    assert "Step 1:" in browser.text()
    browser.screenshot(ARTIFACTS / "app-play.png")
    assert not browser.errors(), browser.errors()
    expected = [
        {"type": "Switch_view", "coord": [250, 750], "params": ["front"]},
        {"type": "Press", "coord": [627, 15], "params": ["0"]},
    ]
    steps = journal_steps(play_server.run)
    assert [s["action"] for s in steps] == expected
    assert steps[0]["feedback"] == "view_switched" and steps[0]["view"] == "front"

    before = browser.run_number()
    browser.page.get_by_role("button", name="Give up").click()
    browser.wait_rendered("Ended by the player", time.monotonic(), after=before)
    assert not list((play_server.run / "playing").glob("*.jsonl"))
    lines = (play_server.run / "episodes.jsonl").read_text().splitlines()
    assert len(lines) == 1
    episode = json.loads(lines[0])
    assert episode["episode_id"] == "ElectricKettle_000-00"
    assert [s["action"] for s in episode["steps"]] == expected

    out = tmp_path / "out"
    replay.replay_runs([play_server.run], play_server.bench, out, progress=False)
    va.clear_cache()
    replayed = va.steps(out).sort("step")
    assert replayed["diverged"].to_list() == [False, False]
    assert replayed.select("x", "y").rows() == [(250.0, 750.0), (627.0, 15.0)]
    assert replayed["action_type"].to_list() == ["switch_view", "press"]
    (row,) = va.episodes(out).iter_rows(named=True)
    assert (row["agent_kind"], row["diverged_steps"], row["n_steps"]) == ("human", 0, 2)
    assert row["termination"] == "log_ended"
    assert not browser.page_errors, browser.page_errors
    print("seconds to rendered:", {k: round(v, 2) for k, v in timings.items()})


def test_a_killed_server_loses_no_step(play_server, page, tmp_path):
    browser = AppPage(page, play_server.server.url)
    browser.open("", "Goal 1 of 1")
    click_image(browser, 240, 240, "Step 0:")  # (500, 500)
    click_image(browser, 48, 432, "Step 1:")  # (100, 900)
    play_server.server.kill()  # as a crash: no clean-up

    options = ["--out", str(play_server.run), "--image-width", str(WIDTH)]
    log = tmp_path / "vge-play-again.log"
    with AppServer(play_server.bench, command="play", options=options, log=log) as server:
        browser = AppPage(page, server.url)
        browser.open("", "2 steps of this episode were played before")
        before = browser.run_number()
        browser.page.get_by_role("button", name="Resume").click()
        browser.wait_rendered("Goal 1 of 1", time.monotonic(), after=before)
        assert "Step 1: Press(coord=[100, 900], params=[0])" in browser.text()
        click_image(browser, 479, 1, "Step 2:")  # 997.92 -> 998, 2.08 -> 2
        before = browser.run_number()
        browser.page.get_by_role("button", name="Give up").click()
        browser.wait_rendered("Ended by the player", time.monotonic(), after=before)
        assert not browser.errors() and not browser.page_errors
    (line,) = (play_server.run / "episodes.jsonl").read_text().splitlines()
    coords = [s["action"]["coord"] for s in json.loads(line)["steps"]]
    assert coords == [[500, 500], [100, 900], [998, 2]]
    out = tmp_path / "out"
    replay.replay_runs([play_server.run], play_server.bench, out, progress=False)
    va.clear_cache()
    assert va.episodes(out)["diverged_steps"].to_list() == [0]
