"""The Play page's state (`PlayState`) over a plain dict: one step per click, the buttons,
messages said once, picking, resuming and giving up."""

from __future__ import annotations

from vge_analytics import play

from .helpers import KETTLE, OVEN, open_run


def test_the_pages_state_acts_once_per_click_and_moves_on(tmp_path, bench) -> None:
    run = open_run(tmp_path / "run", bench)
    state: dict = {}
    desk = play.PlayState(run, state)
    assert desk.episode_id() == "hw_kettle_a" == state["play_episode"]
    state["play_episode"] = OVEN  # picked in the picker
    game = desk.game()
    assert game.episode_id == OVEN and desk.game() is game
    assert desk.click_view() == "dashboard"  # what a Switch_view click is for
    click = {"x": 30, "y": 15, "width": 60, "height": 60, "unix_time": 1}
    state[desk.click_key()] = click
    desk.click()
    desk.click()  # reported again on the next rerun: not a second step
    assert [s["action"] for s in game.steps] == [play.action("Press", (500, 250), ["0"])]
    state["play_action"] = "Rotate"
    state[desk.params_key("Rotate")] = "1, 3"
    state[desk.click_key()] = {**click, "unix_time": 2}
    desk.click()
    state["play_action"] = "Switch_view"
    state[desk.click_key()] = {**click, "unix_time": 3}
    desk.click()
    desk.wait()
    desk.switch_view("back")
    assert [s["action"] for s in game.steps][1:] == [
        play.action("Rotate", (500, 250), ["1", "3"]),
        play.action("Switch_view", (500, 250), ["dashboard"]),
        play.action("Timed_wait"),
        play.action("Switch_view", None, ["back"]),
    ]
    assert desk.message() is None
    state[desk.click_key()] = {"x": 1, "y": 1, "unix_time": 4}  # no size: not a click
    desk.click()
    assert desk.message() == ("error", f"not a click on the image: {state[desk.click_key()]!r}")
    assert desk.message() is None  # said once
    desk.give_up()
    assert game.done and run.status(OVEN).state == "finished"
    desk.pick_next()
    assert state["play_episode"] == "hw_dash_b"
    # Picking another episode leaves the one being played unfinished, to resume.
    game = desk.game()
    game.act(play.action("Timed_wait"))
    state["play_episode"] = KETTLE
    assert desk.game().episode_id == KETTLE and state["play_game"].episode_id == KETTLE
    state["play_episode"] = "hw_dash_b"
    assert desk.game() is None and run.status("hw_dash_b").state == "unfinished"
    desk.resume()
    assert len(desk.game().steps) == 1
    # Giving up before any step writes nothing.
    state["play_episode"] = KETTLE
    desk.give_up()
    assert desk.message() == (
        "info",
        "Nothing was played in this episode, so nothing was written.",
    )
    assert run.status(KETTLE).state == "new"


def test_the_pages_state_says_when_every_episode_is_played(tmp_path, bench) -> None:
    run = open_run(tmp_path / "run", bench)
    state: dict = {}
    desk = play.PlayState(run, state)
    for episode_id in run.bench.tasks:
        state["play_episode"] = episode_id
        desk.wait()
        desk.give_up()
    assert run.next_episode() is None
    desk.pick_next()
    assert desk.message() == (
        "info",
        "Every episode of the benchmark has been played in this run.",
    )
    assert desk.game().done  # the last one played: the page shows its result
