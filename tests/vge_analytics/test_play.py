"""The Play page's logic (`vge_analytics._play`): the click mapping, worked by hand, and the
human run writer: what it writes, that `vge replay` reads it with zero divergent steps, and
what is left after a crash at each point of a write (a torn journal line, a torn episode
line, a journal left behind), resumed or discarded; two windows on one episode."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import orjson
import polars as pl
import pytest

import replay
import vge_analytics as va
from replay.env import no_images
from vge_analytics import _play as play
from vge_analytics._errors import PlayConflictError, PlayError

SCREEN = {"image_source": no_images, "image_size": (40, 30)}
"""Episodes here do not look at the views: no rendering."""
KETTLE = "hw_kettle_c"  # 3 goals, C_opt 1 + 2 + 1 (a chain), λ 2
OVEN = "hw_dash_a"


class Clock:
    """Seconds since the epoch, one more per call (a person taking exactly 1 s a step)."""

    def __init__(self, start: float = 1_760_000_000.0) -> None:
        self.now = start

    def __call__(self) -> float:
        self.now += 1.0
        return self.now


# --------------------------------------------------------------------- click mapping


@pytest.mark.parametrize(
    ("offset", "displayed", "expected"),
    [
        # The page shows the 768-pixel view 600 pixels wide: 1000 * offset / 600.
        (150, 600, 250),  # 250 exactly
        (300, 600, 500),  # the middle
        (301, 600, 502),  # 501.67 -> 502
        (7, 600, 12),  # 11.67 -> 12
        (0, 600, 0),
        (600, 600, 1000),  # the right edge
        # The same image at its natural width: the middle is still 500.
        (384, 768, 500),
        (100, 768, 130),  # 130.21 -> 130
        # Halves round up (Python's round() would give 2 and 0).
        (1, 400, 3),  # 2.5 -> 3
        (0.4, 800, 1),  # 0.5 -> 1
        (1, 800, 1),  # 1.25 -> 1
        (3, 800, 4),  # 3.75 -> 4
        # A click reported just outside the image stays on the scale.
        (-2, 600, 0),
        (605, 600, 1000),
    ],
)
def test_scale_coordinate_worked_by_hand(offset, displayed, expected) -> None:
    assert play.scale_coordinate(offset, displayed) == expected


def test_click_point_uses_the_displayed_size_not_the_natural_one() -> None:
    # A 768 x 768 view shown at 600 x 600: pixel (150, 450) is (250, 750) on the scale.
    assert play.click_point({"x": 150, "y": 450, "width": 600, "height": 600}) == (250, 750)
    # A view shown 600 x 450 (4:3): each axis is scaled by its own displayed size.
    assert play.click_point({"x": 60, "y": 45, "width": 600, "height": 450}) == (100, 100)
    assert play.click_point({"x": 301, "y": 7, "width": 600, "height": 450}) == (502, 16)
    # 7 / 450 * 1000 = 15.56 -> 16.
    with pytest.raises(PlayError, match="displayed size"):
        play.click_point({"x": 1, "y": 1, "width": 0, "height": 600})
    with pytest.raises(PlayError, match="not a click"):
        play.click_point({"x": 1, "y": 1})
    with pytest.raises(PlayError, match="must be a number"):
        play.click_point({"x": float("nan"), "y": 1, "width": 10, "height": 10})


def test_actions_as_a_human_log_carries_them() -> None:
    assert play.parse_params(" 0 , 3,, ") == ["0", "3"]
    assert play.parse_params("") == []
    assert play.click_action("Rotate", (331, 875), "0, 3", "front") == {
        "type": "Rotate",
        "coord": [331, 875],
        "params": ["0", "3"],
    }
    # A Switch_view with a point (how the locked dashboard is unlocked).
    assert play.click_action("Switch_view", (10, 20), "ignored", "dashboard") == {
        "type": "Switch_view",
        "coord": [10, 20],
        "params": ["dashboard"],
    }
    with pytest.raises(PlayError):
        play.click_action("Timed_wait", (1, 2), "", "front")
    assert play.action_text({"action": play.action("Timed_wait")}) == "Timed_wait(params=[])"
    assert play.click_id(None) is None
    assert play.click_id({"x": 1, "y": 2, "unix_time": 5}) == (5, 1, 2)


# ---------------------------------------------------------------------------- the run


def structured(a: replay.Action) -> dict:
    return play.action(a.type.capitalize(), a.coord, a.params)


def optimal_actions(run: play.HumanRun, episode_id: str) -> list[dict]:
    task = run.bench.tasks[episode_id].task
    plan = replay.setup_episode(run.bench.machine(task.device_id), task).plan
    return [structured(s.action) for s in plan.steps]


@pytest.fixture
def bench(hand) -> Path:
    return hand["bench"]


def open_run(root: Path, bench: Path, **settings) -> play.HumanRun:
    return play.HumanRun.open(root, bench, clock=Clock(), **SCREEN, **settings)


def lines(path: Path) -> list[dict]:
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def replay_run(run_dir: Path, bench: Path, out: Path) -> dict[str, pl.DataFrame]:
    replay.replay_runs([str(run_dir)], str(bench), str(out), progress=False)
    va.clear_cache()
    return {"steps": va.steps(out), "episodes": va.episodes(out)}


def test_a_new_run_is_a_human_run_vge_replay_reads(tmp_path, bench) -> None:
    run = open_run(tmp_path / "alice", bench, model="participant-7", lam=3)
    header = replay.read_run_header(run.root)
    assert (header.run_id, header.model, header.agent_kind, header.lam) == (
        "alice",
        "participant-7",
        "human",
        3.0,
    )
    assert header.meta == {"interface": "vge play"}
    assert (run.root / "episodes.jsonl").read_bytes() == b""
    assert replay.validate_run(run.root, replay.Benchmark.open(bench)) == []
    # Opened again: the same run; other settings are refused.
    assert open_run(tmp_path / "alice", bench).header == header
    with pytest.raises(PlayError, match="run_id 'alice', not 'bob'"):
        open_run(tmp_path / "alice", bench, run_id="bob")
    with pytest.raises(PlayError, match="lambda 3.0, not 5"):
        open_run(tmp_path / "alice", bench, lam=5)


def test_a_run_of_another_kind_is_refused(tmp_path, hand) -> None:
    with pytest.raises(PlayError, match="agent kind 'vlm'"):
        open_run(hand["runs"][0], hand["bench"])


def test_an_episode_played_to_success_replays_with_zero_divergence(tmp_path, bench) -> None:
    run = open_run(tmp_path / "run", bench)
    episode = run.start(KETTLE)
    actions = optimal_actions(run, KETTLE)
    assert len(actions) == 4  # C_opt 1 + 2 + 1
    for k, a in enumerate(actions):
        assert not episode.done
        info = episode.act(a)
        assert info["step"] == k
        if k < len(actions) - 1:
            journal = lines(run.journal_path(KETTLE))
            assert journal[0] == {"episode_id": KETTLE} and len(journal) == k + 2
    assert episode.done and episode.result.success and episode.result.spl == 1.0
    assert not run.journal_path(KETTLE).exists()
    (line,) = lines(run.root / "episodes.jsonl")
    assert line["episode_id"] == KETTLE
    first = line["steps"][0]
    assert first["action"] == actions[0]
    assert set(first) == {"action", "view", "feedback", "state", "timestamp"}
    assert [s["timestamp"] for s in line["steps"]] == [1_760_000_001.0 + k for k in range(4)]
    assert first["feedback"] == "transition" and first["state"] == "LidOpen"

    tables = replay_run(run.root, bench, tmp_path / "out")
    steps, episodes = tables["steps"], tables["episodes"]
    assert steps.height == 4 and steps["diverged"].to_list() == [False] * 4
    assert episodes["diverged_steps"].to_list() == [0] and episodes["success"].to_list() == [True]
    assert episodes["agent_kind"].to_list() == ["human"]
    clicks = [a["coord"] for a in actions]
    got = [None if x is None else [x, y] for x, y in steps.select("x", "y").iter_rows()]
    assert got == clicks
    assert [s.episode_id for s in run.statuses() if s.state == "finished"] == [KETTLE]
    result, row = run.result(KETTLE), episodes.row(0, named=True)
    assert (result.success, result.spl, result.L_act, result.L_opt) == (
        row["success"], row["spl"], row["L_act"], row["L_opt"]
    )  # fmt: skip
    assert result == episode.result
    with pytest.raises(PlayError, match="already played"):
        run.start(KETTLE)


def test_ending_early_writes_a_log_ended_episode(tmp_path, bench) -> None:
    run = open_run(tmp_path / "run", bench)
    episode = run.start(KETTLE)
    assert episode.end() is None  # nothing played, nothing written
    assert run.status(KETTLE).state == "new" and not lines(run.root / "episodes.jsonl")
    episode = run.start(KETTLE)
    info = episode.act(play.action("Press", (1, 1), ["0"]))
    assert info["feedback_kind"] == "null_effect"
    result = episode.end()
    assert result.termination == "log_ended" and not result.success
    assert run.status(KETTLE) == play.EpisodeStatus(KETTLE, "kettle", 3, "finished", 1)
    episodes = replay_run(run.root, bench, tmp_path / "out")["episodes"]
    assert episodes["termination"].to_list() == ["log_ended"]
    assert episodes["diverged_steps"].to_list() == [0]


def test_a_torn_journal_line_is_cut_off_and_the_episode_resumed(tmp_path, bench) -> None:
    run = open_run(tmp_path / "run", bench)
    actions = optimal_actions(run, KETTLE)
    episode = run.start(KETTLE)
    episode.act(actions[0])
    episode.act(actions[1])
    journal = run.journal_path(KETTLE)
    good = journal.read_bytes()
    # The app dies in the middle of writing step 2 (its feedback was never shown).
    with journal.open("ab") as fh:
        fh.write(b'{"action":{"type":"Pu')
    del episode

    run = open_run(tmp_path / "run", bench)
    assert run.status(KETTLE) == play.EpisodeStatus(KETTLE, "kettle", 3, "unfinished", 2)
    assert run.next_episode() == next(iter(run.bench.tasks))  # none is played to its end
    with pytest.raises(PlayError, match="resume or discard"):
        run.start(KETTLE)
    episode = run.resume(KETTLE)
    assert journal.read_bytes() == good
    assert len(episode.steps) == 2 and episode.observation["step"] == 2
    assert episode.observation["goal_index"] == 1
    for a in actions[2:]:
        episode.act(a)
    assert episode.result.success and not journal.exists()
    (line,) = lines(run.root / "episodes.jsonl")
    assert [s["action"] for s in line["steps"]] == actions
    episodes = replay_run(run.root, bench, tmp_path / "out")["episodes"]
    assert episodes["diverged_steps"].to_list() == [0] and episodes["success"].to_list() == [True]


def test_a_torn_episode_line_is_cut_off_and_the_episode_finished_from_its_journal(
    tmp_path, bench, monkeypatch
) -> None:
    run = open_run(tmp_path / "run", bench)
    actions = optimal_actions(run, KETTLE)
    # A first episode, ended: its line must survive the repair untouched.
    first = run.start(OVEN)
    first.act(play.action("Timed_wait"))
    first.end()
    before = (run.root / "episodes.jsonl").read_bytes()

    def crash(self, episode_id, steps):  # the app dies half-way through the episode line
        data = orjson.dumps({"episode_id": episode_id, "steps": steps}) + b"\n"
        with (self.root / "episodes.jsonl").open("ab") as fh:
            fh.write(data[: len(data) // 2])
        raise KeyboardInterrupt

    episode = run.start(KETTLE)
    for a in actions[:-1]:
        episode.act(a)
    monkeypatch.setattr(play.HumanRun, "_append_episode", crash)
    with pytest.raises(KeyboardInterrupt):
        episode.act(actions[-1])  # the last step: journalled, then the episode line is torn
    monkeypatch.undo()
    assert len(lines(run.journal_path(KETTLE))) == 5

    run = open_run(tmp_path / "run", bench)
    assert (run.root / "episodes.jsonl").read_bytes() == before
    (torn,) = (run.root / "playing" / "discarded").iterdir()  # kept aside, not lost
    assert torn.name == "episodes-tail.1.jsonl" and torn.read_bytes().startswith(b'{"episode_id"')
    assert run.status(KETTLE).state == "unfinished"
    episode = run.resume(KETTLE)
    assert episode.done and episode.result.success  # finished at once
    assert not run.journal_path(KETTLE).exists()
    got = lines(run.root / "episodes.jsonl")
    assert [g["episode_id"] for g in got] == [OVEN, KETTLE]
    assert [s["action"] for s in got[1]["steps"]] == actions
    episodes = replay_run(run.root, bench, tmp_path / "out")["episodes"]
    assert episodes["diverged_steps"].to_list() == [0, 0]


def test_a_journal_left_behind_by_a_finished_episode_is_removed(tmp_path, bench) -> None:
    run = open_run(tmp_path / "run", bench)
    actions = optimal_actions(run, KETTLE)
    episode = run.start(KETTLE)
    for a in actions[:-1]:
        episode.act(a)
    kept = run.journal_path(KETTLE).read_bytes()
    episode.act(actions[-1])
    # The app died after the episode line was written, before the journal was removed.
    run.journal_path(KETTLE).write_bytes(kept + orjson.dumps(episode.steps[-1]) + b"\n")
    run = open_run(tmp_path / "run", bench)
    assert not run.journal_path(KETTLE).exists()
    assert run.status(KETTLE).state == "finished" and len(lines(run.episodes_path)) == 1
    # A journal whose very first write was torn holds nothing a person saw.
    torn = run.journal_path(OVEN)
    torn.write_bytes(b'{"episode_id":"hw_da')
    run = open_run(tmp_path / "run", bench)
    assert not torn.exists() and run.status(OVEN).state == "new"


def test_a_hand_written_last_line_without_newline_is_kept(tmp_path, bench) -> None:
    root = tmp_path / "run"
    open_run(root, bench)
    line = orjson.dumps({"episode_id": OVEN, "steps": [{"action": play.action("Timed_wait")}]})
    (root / "episodes.jsonl").write_bytes(line)
    run = open_run(root, bench)
    assert (root / "episodes.jsonl").read_bytes() == line + b"\n"
    assert run.status(OVEN).state == "finished"


def test_discarding_keeps_the_journal_aside_and_the_episode_starts_over(tmp_path, bench) -> None:
    run = open_run(tmp_path / "run", bench)
    for n in (1, 2):
        episode = run.start(KETTLE)
        episode.act(play.action("Press", (1, 1), ["0"]))
        target = run.discard(KETTLE)
        assert target == run.root / "playing" / "discarded" / (
            run.journal_path(KETTLE).stem + f".{n}.jsonl"
        )
        assert len(lines(target)) == 2 and run.status(KETTLE).state == "new"
    with pytest.raises(PlayError, match="no unfinished steps"):
        run.discard(KETTLE)
    with pytest.raises(PlayError, match="no unfinished steps"):
        run.resume(KETTLE)
    # The discarded journals are not part of the run.
    assert replay_run(run.root, bench, tmp_path / "out")["episodes"].height == 0


def test_a_journal_the_environment_no_longer_agrees_with_is_not_resumed(tmp_path, bench) -> None:
    run = open_run(tmp_path / "run", bench)
    episode = run.start(KETTLE)
    episode.act(optimal_actions(run, KETTLE)[0])
    path = run.journal_path(KETTLE)
    path.write_bytes(path.read_bytes().replace(b'"state":"LidOpen"', b'"state":"Standby"'))
    with pytest.raises(PlayError, match="step 0 of its journal now gives another state"):
        run.resume(KETTLE)
    path.write_bytes(path.read_bytes() + b"not json\n")
    with pytest.raises(PlayError, match="line 3 is not a step"):
        run.resume(KETTLE)
    assert run.status(KETTLE).state == "unfinished"  # the picker still lists it
    run.discard(KETTLE)


def test_two_windows_on_one_episode_do_not_interleave(tmp_path, bench) -> None:
    run = open_run(tmp_path / "run", bench)  # λ 5: three steps do not end the episode
    press = play.action("Press", (1, 1), ["0"])
    a = run.start(OVEN)
    b = run.start(OVEN)  # both opened before either played
    a.act(press)
    with pytest.raises(PlayConflictError, match="another window"):
        b.act(press)
    a2 = run.resume(OVEN)
    a2.act(press)
    with pytest.raises(PlayConflictError, match="another window"):
        a.act(press)  # a2 played on
    run.discard(OVEN)
    with pytest.raises(PlayConflictError):
        a2.end()
    assert lines(run.root / "episodes.jsonl") == []


def test_next_episode_skips_finished_and_unplayable_tasks(tmp_path, bench) -> None:
    bad = tmp_path / "bench"
    shutil.copytree(bench, bad)
    tasks = (bad / "tasks.jsonl").read_text().splitlines()
    ghost = {"episode_id": "ghost", "device_id": "no-such-device", "goals": ["On"]}
    (bad / "tasks.jsonl").write_text("\n".join([json.dumps(ghost), *tasks]) + "\n")
    run = open_run(tmp_path / "run", bad)
    ids = [json.loads(t)["episode_id"] for t in tasks]
    assert [s.episode_id for s in run.statuses()] == ["ghost", *ids]
    assert not run.playable("ghost")
    assert run.next_episode() == ids[0]
    episode = run.start(ids[0])
    episode.act(play.action("Timed_wait"))
    episode.end()
    assert run.next_episode() == ids[1]
    assert run.next_episode(after=ids[2]) == ids[3]
    assert run.next_episode(after=ids[-1]) == ids[1]  # wraps around
    assert run.status(ids[0]).label() == f"{ids[0]} · kettle · 2 goals"
    assert run.status(ids[0]).summary() == "Played to its end in 1 step."
    assert run.status(ids[1]).label() == f"{ids[1]} · kettle · 1 goal"
    assert run.status(ids[1]).summary() == "Not played in this run yet."


# ------------------------------------------------------------------------ the page's state


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
