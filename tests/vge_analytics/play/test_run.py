"""The human run writer: what it writes, that `vge replay` reads it with zero divergent steps,
and what is left after a crash at each point of a write (a torn journal line, a torn episode
line, a journal left behind), resumed or discarded; two windows on one episode."""

from __future__ import annotations

import json
import shutil

import orjson
import pytest

import replay
from vge_analytics import play
from vge_analytics._errors import PlayConflictError, PlayError

from .helpers import KETTLE, OVEN, lines, open_run, optimal_actions, replay_run


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
