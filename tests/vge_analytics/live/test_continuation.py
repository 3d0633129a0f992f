"""Continuation runs (`vge run --from RUN_DIR --at K|first-error [--fix]`, PROTOCOL §10.4),
worked by hand on the kettle, and the two metrics of continuation runs (PROTOCOL §6).

The task `three` (the kettle's hand-worked case c, λ 2, from the right view): open the lid
(C_opt 1), then boil (3: close the lid, push the power button, wait; the immediate return to
Standby completes the third goal in the same step). The source run `src`:

| episode | source steps | first error | source |
|---|---|---|---|
| three | open the lid (LidOpen), then a push at x 1200 (`invalid_coord`) and two waits | step 1 | fails (its log ends) |
| open-lid | open the lid | none | succeeds at step 0 |

`--at first-error --fix`: `three` replays step 0 (prefix), then the planner's step from
LidOpen in the right view (§4.5: close the lid, `Push(coord=[481, 92], params=[0])`, which
makes progress: 3 steps from BoilingComplete become 2), then a scripted agent pushes the
power button and waits: success in 1 + 1 + 2 = 4 scored steps, 2 of them the agent's.
`open-lid` has no error: copied as it was. RecoveryRate = 1 recovered / 1 continued episode
whose source failed = 100 %; StepsToRecover = 2.

`--at 1` without the fix: `three` replays step 0, then the agent closes the lid, pushes the
power button and waits: 3 agent steps. `open-lid` terminated within its first step: copied.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

import replay
import vge_analytics as va
from vge_analytics.cli import main

from .chat_server import answer, chat_server
from .conftest import DATA, OPEN_LID

THREE = json.loads((DATA / "hand_worked" / "kettle_c_parse_multigoal_chain.json").read_text())
OPEN = "Thinking: The lid.\nAction: Push(coord=[480, 90], params=[1])"
CLOSE = "Thinking: Close the lid.\nAction: Push(coord=[480, 90], params=[0])"
POWER = "Thinking: The power switch.\nAction: Push(coord=[500, 850], params=[1])"
WAIT = "Thinking: It heats.\nAction: Timed_wait()"
FAR = "Thinking: Close it.\nAction: Push(coord=[1200, 90], params=[0])"

AGENTS = f"""
class Scripted:
    def __init__(self, answers):
        self.answers = answers

    def reset(self, obs):
        self.left = list(self.answers)

    def __call__(self, obs):
        return self.left.pop(0)


after_fix = Scripted({[POWER, WAIT]!r})
after_cut = Scripted({[CLOSE, POWER, WAIT]!r})
"""


@pytest.fixture
def source(kettle_bench: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    with (kettle_bench / "tasks.jsonl").open("a") as fh:
        fh.write(json.dumps({**THREE["task"], "episode_id": "three"}) + "\n")
    run = tmp_path / "src"
    run.mkdir()
    header = {"run_id": "src", "model": "m", "agent_kind": "vlm", "lambda": 2, "meta": {}}
    (run / "run.json").write_text(json.dumps(header))
    lines = [
        {"episode_id": "three", "steps": [{"output": s} for s in (OPEN, FAR, WAIT, WAIT)]},
        {"episode_id": "open-lid", "steps": [{"output": OPEN_LID}]},
    ]
    (run / "episodes.jsonl").write_text("".join(json.dumps(x) + "\n" for x in lines))
    (tmp_path / "scripted.py").write_text(AGENTS)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "scripted", raising=False)
    return run


def _continue(bench: Path, source: Path, out: Path, agent: str, *extra: str) -> int:
    args = ["run", str(bench), "--agent", f"scripted:{agent}", "--from", str(source)]
    return main([*args, "--out", str(out), "--no-progress", *extra])


def _lines(run: Path) -> dict[str, dict]:
    return {
        d["episode_id"]: d
        for d in map(json.loads, (run / "episodes.jsonl").read_text().splitlines())
    }


def test_first_error_fixed_then_finished_by_a_scripted_agent(
    kettle_bench: Path, source: Path, tmp_path: Path
) -> None:
    cont = tmp_path / "fixed"
    assert _continue(kettle_bench, source, cont, "after_fix", "--at", "first-error", "--fix") == 0
    meta = replay.read_run_header(cont).meta
    assert meta["counterfactual"] == {"from_run": "src", "at": "first-error", "fix": True}
    assert replay.read_run_header(cont).lam == 2.0  # the source's λ
    lines = _lines(cont)
    assert list(lines) == ["three", "open-lid"]  # the source's order
    three = lines["three"]
    assert three["continuation"] == {
        "prefix_steps": 1, "fixed": True, "continued": True, "source_success": False,
    }  # fmt: skip
    assert [s.get("output") for s in three["steps"]] == [OPEN, None, POWER, WAIT]
    assert three["steps"][1]["action"] == {"type": "Push", "coord": [481.0, 92.0], "params": ["0"]}
    assert [s["state"] for s in three["steps"]] == ["LidOpen", "Standby", "Boiling", "Standby"]
    assert lines["open-lid"]["continuation"] == {
        "prefix_steps": 1, "fixed": False, "continued": False, "source_success": True,
    }  # fmt: skip

    out = tmp_path / "out"
    manifest = replay.replay_runs([source, cont], kettle_bench, out, progress=False)
    assert manifest.run("fixed").counts.diverged_steps == 0
    steps = va.sql(
        out,
        "SELECT step, origin, progress, state_after, truncated FROM steps "
        "WHERE run_id = 'fixed' AND episode_id = 'three' ORDER BY step",
    ).rows()
    assert steps == [
        (0, "prefix", True, "LidOpen", False),
        (1, "fix", True, "Standby", False),
        (2, "agent", True, "Boiling", False),
        (3, "agent", True, "Standby", False),
    ]
    episodes = {e["episode_id"]: e for e in va.episodes(out, where={"run_id": "fixed"}).to_dicts()}
    e = episodes["three"]
    assert (e["success"], e["L_act"], e["prefix_steps"], e["fixed"]) == (True, 4, 1, True)
    assert (e["continued"], e["source_success"]) == (True, False)
    m = va.metrics(out, metrics="continuation").select("run_id", "RecoveryRate", "StepsToRecover")
    assert m.rows() == [("fixed", 100.0, 2.0), ("src", None, None)]  # an ordinary run: none


def test_cut_after_k_steps_without_the_fix(
    kettle_bench: Path, source: Path, tmp_path: Path
) -> None:
    cont = tmp_path / "cut"
    assert _continue(kettle_bench, source, cont, "after_cut", "--at", "1") == 0
    lines = _lines(cont)
    assert [s["output"] for s in lines["three"]["steps"]] == [OPEN, CLOSE, POWER, WAIT]
    assert lines["three"]["continuation"]["prefix_steps"] == 1
    assert lines["three"]["continuation"]["fixed"] is False
    # open-lid succeeded in its first step: nothing left to continue
    assert lines["open-lid"]["continuation"]["continued"] is False
    out = tmp_path / "out"
    replay.replay_runs([cont], kettle_bench, out, progress=False)
    origins = va.sql(out, "SELECT origin FROM steps WHERE episode_id = 'three' ORDER BY step")
    assert origins["origin"].to_list() == ["prefix", "agent", "agent", "agent"]
    m = va.metrics(out, metrics="continuation").row(0, named=True)
    assert (m["RecoveryRate"], m["StepsToRecover"]) == (100.0, 3.0)


def test_options_that_do_not_make_a_continuation(
    kettle_bench: Path, source: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    def error(*args: str) -> str:
        assert main(["run", str(kettle_bench), "--agent", "sim:f", *args, "--no-progress"]) == 1
        return capsys.readouterr().err.strip()

    out = ["--out", str(tmp_path / "x")]
    assert error(*out, "--at", "3") == (
        "error: --at and --fix continue another run: they need --from RUN_DIR"
    )
    assert error(*out, "--from", str(source)).startswith("error: --from ")
    assert error(*out, "--from", str(source), "--at", "soon") == (
        "error: --at takes a number of steps or first-error, not 'soon'"
    )
    assert "plays under its source's lambda (2," in error(
        *out, "--from", str(source), "--at", "1", "--lambda", "5"
    )
    assert "not in" in error(*out, "--from", str(source), "--at", "1", "--episodes", "boil")
    assert "cannot continue itself" in error(
        "--out", str(source), "--from", str(source), "--at", "1"
    )
    assert not (tmp_path / "x").exists()


def test_an_openai_agent_hears_the_steps_before_the_cut_as_its_own(
    kettle_bench: Path, source: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The model's conversation at the cut holds the prefix step and the fix as its own
    earlier answers (the fix as the call the planner made), each with what happened."""
    monkeypatch.delenv("OPENAI_API_KEY", raising=False)
    cont = tmp_path / "vlm"
    with chat_server([answer(POWER), answer(WAIT)]) as server:
        code = main(
            [
                "run", str(kettle_bench), "--agent", "openai:scripted-vlm", "--out", str(cont),
                "--base-url", server.url, "--no-progress", "--from", str(source),
                "--at", "first-error", "--fix",
            ]
        )  # fmt: skip
    assert code == 0 and len(server.requests) == 2  # open-lid is copied: no request
    messages = server.requests[0]["body"]["messages"]
    assert [m["role"] for m in messages] == [
        "system",
        "user",
        "assistant",
        "user",
        "assistant",
        "user",
    ]
    assert messages[2]["content"] == OPEN
    assert messages[4]["content"] == "Action: Push(coord=[481, 92], params=[0])"
    assert "This is your first action." in messages[1]["content"][0]["text"]
    last = messages[5]["content"][0]["text"]
    assert "Your last action: Push(coord=[481, 92], params=[0])" in last
    assert "(part 2 of 3 of the task)" in last
    steps = _lines(cont)["three"]["steps"]
    assert [s.get("prompt_tokens") for s in steps] == [None, None, 1000, 1000]  # the agent's only


def test_both_engines_replay_a_continuation_to_the_same_files(
    kettle_bench: Path, source: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    cont = tmp_path / "fixed"
    assert _continue(kettle_bench, source, cont, "after_fix", "--at", "first-error", "--fix") == 0
    files = {}
    for engine in ("reference", "kernel"):
        monkeypatch.setattr("replay.io._batch.KERNEL", engine == "kernel")
        out = tmp_path / engine
        replay.replay_runs([cont], kettle_bench, out, progress=False)
        files[engine] = {str(p.relative_to(out)): p.read_bytes() for p in out.rglob("*.parquet")}
    assert files["reference"] == files["kernel"] and len(files["kernel"]) == 4


def test_source_lines_that_are_not_episodes_are_named_and_the_run_is_not_complete(
    kettle_bench: Path, source: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Lines of the source that the replay would quarantine (not JSON, a step that is not a
    step, a byte that is not UTF-8) cannot be continued: each is named with its file and
    line, the others are continued, and the run says it is not complete."""
    episodes = source / "episodes.jsonl"
    good = episodes.read_bytes().splitlines(keepends=True)
    bad = [
        b"not json\n",
        b'{"episode_id": "boil", "steps": [{"output": 5}]}\n',
        b'{"episode_id": "\xff", "steps": []}\n',
    ]
    episodes.write_bytes(good[0] + b"".join(bad) + good[1])
    cont = tmp_path / "cut"
    assert _continue(kettle_bench, source, cont, "after_cut", "--at", "1") == 0
    shown = [x for x in capsys.readouterr().out.splitlines() if x.startswith("not playable")]
    assert [x.split(": not an episode record, not continued (")[0] for x in shown] == [
        f"not playable: {episodes} line {n}" for n in (2, 3, 4)
    ]
    assert "Expected `str | null`, got `int` - at `$.steps[0].output`" in shown[1]
    assert list(_lines(cont)) == ["three", "open-lid"]
    meta = replay.read_run_header(cont).meta
    assert (meta["episodes"], meta["complete"], meta["source_lines_unread"]) == (2, False, 3)

    # Named episodes: the selection is whole, the run complete.
    named = tmp_path / "named"
    assert (
        _continue(
            kettle_bench, source, named, "after_cut", "--at", "1", "--episodes", "three,open-lid"
        )
        == 0
    )
    meta = replay.read_run_header(named).meta
    assert meta["complete"] is True and "source_lines_unread" not in meta


def test_many_unreadable_source_lines_are_counted_not_listed(
    kettle_bench: Path, source: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    episodes = source / "episodes.jsonl"
    episodes.write_bytes(episodes.read_bytes() + b"[]\n" * 5000)
    assert _continue(kettle_bench, source, tmp_path / "cut", "after_cut", "--at", "1") == 0
    shown = [x for x in capsys.readouterr().out.splitlines() if x.startswith("not playable")]
    assert len(shown) == 11 and f"line {2 + 10}:" in shown[9]  # lines 3 to 12
    assert shown[10] == f"not playable: {episodes}: 4,990 more lines that are not episode records"
    assert replay.read_run_header(tmp_path / "cut").meta["source_lines_unread"] == 5000
