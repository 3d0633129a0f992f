"""`module:callable` agents: a run killed mid-way (a real process, SIGKILL) and resumed is
byte-identical to an uninterrupted one; loading and calling errors are one line."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pyarrow.parquet as pq
import pytest

import replay
from vge_analytics.cli import main

# A deterministic agent: its answer depends on the observation only. `AGENT_SLEEP` slows it
# down (for the run that gets killed); it never changes what it answers.
AGENT = """
import hashlib, os, time

SLEEP = float(os.environ.get("AGENT_SLEEP", "0"))


class Agent:
    def reset(self, obs):
        self.episode = obs["episode_id"]

    def __call__(self, obs):
        time.sleep(SLEEP)
        assert obs["episode_id"] == self.episode and obs["image"].shape == (768, 768, 3)
        digest = hashlib.sha256(f"{self.episode}/{obs['step']}".encode()).digest()
        if digest[0] % 4 == 0:
            return "Thinking: the lid.\\nAction: Push(coord=[480, 90], params=[1])"
        if digest[0] % 4 == 1:
            return {"type": "Push", "coord": [780, 725], "params": [1]}
        if digest[0] % 4 == 2:
            return "Action: Timed_wait()"
        return f"Action: Press(coord=[{digest[1] * 4}, {digest[2] * 4}], params=[0])"


agent = Agent()
NOT_CALLABLE = 42


def returns_int(obs):
    return 7


def bad_action(obs):
    return {"type": "Press", "coord": "middle"}


def raises(obs):
    raise RuntimeError("the model\\nfell over")


def long_context(obs):
    # Wraps a model of its own, whose context window is full after one step.
    from vge_analytics import ContextExceededError

    if obs["step"] >= 1:
        raise ContextExceededError("8192 tokens at most")
    return "Thinking: the power.\\nAction: Push(coord=[780, 725], params=[0])"
"""


@pytest.fixture
def agent_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """The current directory holds `liveagent.py` (and `brokenagent.py`, which fails to
    import); `vge run` imports agents from there."""
    folder = tmp_path / "agents"
    folder.mkdir()
    (folder / "liveagent.py").write_text(AGENT)
    (folder / "brokenagent.py").write_text("raise ValueError('no weights here')\n")
    monkeypatch.chdir(folder)
    monkeypatch.delitem(sys.modules, "liveagent", raising=False)
    return folder


def _args(bench: Path, out: Path, *extra: str) -> list[str]:
    return ["run", str(bench), "--agent", "liveagent:agent", "--out", str(out)] + [
        "--run-id", "r", "--no-progress", *extra,
    ]  # fmt: skip


def _files(run: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(run.iterdir())}


def test_a_killed_run_resumed_is_byte_identical_to_an_uninterrupted_one(
    many_tasks: Path, agent_dir: Path, tmp_path: Path
) -> None:
    whole = tmp_path / "whole"
    assert main(_args(many_tasks, whole)) == 0

    killed = tmp_path / "killed"
    env = {**os.environ, "AGENT_SLEEP": "0.05"}
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "vge_analytics.cli",
            *_args(many_tasks, killed, "--concurrency", "2"),
        ],
        cwd=agent_dir,
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    episodes = killed / "episodes.jsonl"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        if episodes.exists() and episodes.read_bytes().count(b"\n") >= 3:
            break
        assert proc.poll() is None, proc.stderr.read().decode()  # type: ignore[union-attr]
        time.sleep(0.02)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    proc.stderr.close()  # type: ignore[union-attr]
    written = episodes.read_bytes().count(b"\n")
    assert 3 <= written < 24, "the run was not interrupted mid-way"
    assert replay.read_run_header(killed).meta["complete"] is False
    # As if the crash had cut a line short: it is dropped, and its episode played again.
    with open(episodes, "ab") as fh:
        fh.write(b'{"episode_id":"boil-11","steps":[{"output":"Act')

    assert main(_args(many_tasks, killed, "--resume", "--concurrency", "3")) == 0
    assert _files(killed) == _files(whole)
    assert sorted(_files(whole)) == ["episodes.jsonl", "run.json"]
    meta = replay.read_run_header(whole).meta
    assert (meta["episodes"], meta["complete"], meta["agent"]) == (24, True, "liveagent:agent")
    assert "latency_seconds" not in meta and "prompt_tokens" not in meta
    # The run replays with zero divergence.
    counts = replay.replay_runs([whole], many_tasks, tmp_path / "out", progress=False).run("r")
    assert (counts.counts.replayed, counts.counts.diverged_steps) == (24, 0)


def test_a_run_extended_by_resume_is_byte_identical_to_one_run_of_the_whole_selection(
    many_tasks: Path, agent_dir: Path, tmp_path: Path
) -> None:
    """`--resume` with a larger selection (`--limit`, `--episodes`) plays the new episodes
    only; the files are in the order of the last selection, as if it had been played at once."""
    whole = tmp_path / "whole"
    assert main(_args(many_tasks, whole)) == 0
    ids = list(replay.Benchmark.open(many_tasks).tasks)
    grown = tmp_path / "grown"
    assert main(_args(many_tasks, grown, "--limit", "5")) == 0
    meta = replay.read_run_header(grown).meta
    assert (meta["episodes_selected"], meta["episodes"], meta["complete"]) == (5, 5, True)
    middle = ids[12:16] + ids[:5]  # 4 more, another order
    assert main(_args(many_tasks, grown, "--resume", "--episodes", ",".join(middle))) == 0
    lines = (grown / "episodes.jsonl").read_text().splitlines()
    assert [json.loads(line)["episode_id"] for line in lines] == middle
    meta = replay.read_run_header(grown).meta
    assert (meta["episodes_selected"], meta["episodes"], meta["complete"]) == (9, 9, True)
    assert main(_args(many_tasks, grown, "--resume", "--concurrency", "3")) == 0
    assert _files(grown) == _files(whole)


def test_a_module_agent_may_end_an_episode_on_its_context_window(
    kettle_bench: Path, agent_dir: Path, tmp_path: Path
) -> None:
    """A callable that raises `ContextExceededError` ends its episode as `context_exceeded`
    (after the step it answered), as an `openai:` agent does on a context-length refusal."""
    run = tmp_path / "run"
    assert main(["run", str(kettle_bench), "--agent", "liveagent:long_context", "--out", str(run),
                 "--no-progress"]) == 0  # fmt: skip
    lines = [json.loads(line) for line in (run / "episodes.jsonl").read_text().splitlines()]
    assert [(e["episode_id"], len(e["steps"]), e.get("ended")) for e in lines] == [
        ("open-lid", 1, "context_exceeded"),
        ("boil", 1, "context_exceeded"),
    ]
    out = tmp_path / "out"
    replay.replay_runs([run], kettle_bench, out, progress=False)
    episodes = pq.read_table(out / "episodes", partitioning=None)
    assert episodes["termination"].to_pylist() == ["context_exceeded"] * 2


@pytest.mark.parametrize(
    ("agent", "message"),
    [
        ("nocolon", "agent 'nocolon': expected module:callable, sim:PROFILE or openai:MODEL"),
        ("nosuchmodule:agent", "agent nosuchmodule:agent: no module named 'nosuchmodule' in"),
        (
            "brokenagent:agent",
            "agent brokenagent:agent: importing brokenagent failed: ValueError: no weights here",
        ),
        ("liveagent:missing", "agent liveagent:missing: liveagent has no attribute 'missing'"),
        ("liveagent:NOT_CALLABLE", "agent liveagent:NOT_CALLABLE: NOT_CALLABLE is a int, not"),
        ("liveagent:returns_int", "agent liveagent:returns_int returned int: an agent returns"),
        (
            "liveagent:raises",
            "agent liveagent:raises raised RuntimeError: the model fell over (episode 'open-lid'",
        ),
        (
            "liveagent:bad_action",
            "agent liveagent:bad_action: structured action {'type': 'Press', 'coord': 'middle'}:",
        ),
        ("sim:nobody", "agent sim:nobody: no such profile; the profiles are sim-vlm-a"),
    ],
)
def test_agent_errors_are_one_line(
    kettle_bench: Path,
    agent_dir: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    agent: str,
    message: str,
) -> None:
    code = main(["run", str(kettle_bench), "--agent", agent, "--out", str(tmp_path / "run")])
    err = capsys.readouterr().err
    assert code == 1
    assert err.startswith(f"error: {message}"), err
    assert err.count("\n") == 1


def test_an_occupied_run_directory_needs_resume(
    kettle_bench: Path, agent_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = tmp_path / "run"
    run.mkdir()
    (run / "notes.txt").write_text("mine")
    assert main(_args(kettle_bench, run)) == 1
    assert "is not empty: --resume completes the run it holds" in capsys.readouterr().err
    assert main(_args(kettle_bench, tmp_path / "fresh", "--resume")) == 1
    assert "no run.json, nothing to resume" in capsys.readouterr().err
