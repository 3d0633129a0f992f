"""Episode lines decoded straight into the kernel's structs (`decode_line`, a `LogLine`) give
the tables of the same lines decoded by msgspec (and so the reference's: test_kernel.py).

The corpus of the kernel's tests, each log written back as a line by `msgspec.json.encode`:
every line the decoder may take (no structured action, no continuation) is taken, and the
others are left to msgspec, in the same batches."""

from __future__ import annotations

import msgspec
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import replay
from replay.kernel import EpisodeInput, LogLine, decode_line, replay_kernel

from . import test_step_in
from .test_kernel import (
    _case_docs,
    _machines,
    _sample_batches,
    _ssm_file,
    _step,
    assert_same,
    episode,
    machine_of,
)


def _takeable(log: replay.EpisodeLog) -> bool:
    return log.continuation is None and all(s.action is None for s in log.steps)


def as_lines(episodes: list[EpisodeInput]) -> tuple[list[EpisodeInput], int]:
    """The episodes with their logs decoded from msgspec's encoding of them by `decode_line`
    (msgspec's log where it declines), and how many it took: all it may take."""
    out = []
    taken = 0
    for e in episodes:
        raw = msgspec.json.encode(e.log)
        line = decode_line(raw)
        if _takeable(e.log):
            assert type(line) is LogLine, f"declined: {raw[:200]!r}"
        if line is None:
            out.append(e)
            continue
        assert line.raw == raw and line.episode_id == e.log.episode_id
        assert line.ended == e.log.ended and len(line) == len(e.log.steps)
        out.append(e._replace(log=line))
        taken += 1
    return out, taken


def check_lines(episodes: list[EpisodeInput]) -> int:
    """The kernel's tables of the episodes as decoded lines equal those of msgspec's logs;
    returns how many lines the decoder took."""
    lines, taken = as_lines(episodes)
    want = replay_kernel(episodes, run_id="run", model="model", agent_kind="vlm")
    got = replay_kernel(lines, run_id="run", model="model", agent_kind="vlm")
    assert_same(got.steps, want.steps, "steps")
    assert_same(got.episodes, want.episodes, "episodes")
    assert_same(got.goals, want.goals, "goals")
    assert list(got.step_counts) == list(want.step_counts)
    assert list(got.goal_counts) == list(want.goal_counts)
    return taken


def test_hand_worked_cases_as_lines() -> None:
    """Every case, and each once more with an empty log, in one batch (structured actions
    among them: those lines stay msgspec's)."""
    batch = []
    for doc in _case_docs():
        machine = machine_of(_ssm_file(doc["ssm"]), doc["device_id"])
        task = msgspec.convert(doc["task"], replay.Task)
        batch.append(episode(machine, task, doc["episode"]["steps"], float(doc["lambda"])))
        batch.append(episode(machine, task, [], float(doc["lambda"])))
    assert check_lines(batch) >= len(batch) // 2


def test_bundled_sample_as_lines() -> None:
    taken = total = 0
    for run, batch in _sample_batches(200):
        try:
            taken += check_lines(batch)
        except AssertionError as exc:
            raise AssertionError(f"run {run}: {exc}") from None
        total += len(batch)
    assert taken > 0 and total > 0


def test_texts_outside_ascii_and_timestamps_as_lines() -> None:
    """The cases of test_step_in.py (Kelvin-sign views, feedback and states outside ASCII,
    each kind of timestamp) through decoded lines."""
    m, task = test_step_in._cafe()
    switch, press = test_step_in.SWITCH.format("back"), test_step_in.PRESS
    views = ["bac\u212a", "BACK", "ba\u0441k", "Back ", None]
    stamps = [1_700_000_000.5, 1_700_000_001, "2026-01-02T03:04:05Z", "\u00a0soon", None]
    steps = [
        {"output": switch, "view": v, "timestamp": t, "prompt_tokens": 7, "latency_seconds": 0.5}
        for v, t in zip(views, stamps, strict=True)
    ]
    steps += [
        {"output": press, "feedback": "Allumé ☕.", "state": "Marche"},
        {"output": press, "feedback": "Éteint", "state": "Arrét", "completion_tokens": 3},
        {"output": "Thinking: ça.\nAction: Press(coord=[125, 125], params=[é])"},  # the reference
        {"feedback": "transition", "view": "front"},  # no output: no action
    ]
    two_goals = replay.Task(episode_id="cafe2", device_id="dev", goals=["Marche", "Arrêt"])
    batch = [episode(m, two_goals, steps, 20.0), episode(m, task, steps, 20.0)]
    assert check_lines(batch) == 2


@st.composite
def _text_episodes(draw) -> list[EpisodeInput]:
    """1-3 episodes of generated text steps (test_kernel's, without structured actions):
    outputs well-formed and broken, texts outside ASCII, recorded values, timestamps."""
    out = []
    for _ in range(draw(st.integers(1, 3))):
        machine, tasks = draw(st.sampled_from(_machines()))
        steps = draw(st.lists(_step(machine).filter(lambda s: "action" not in s), max_size=12))
        lam = draw(st.sampled_from([0.7, 1.5, 5.0]))
        out.append(episode(machine, draw(st.sampled_from(tasks)), steps, lam))
    return out


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_text_episodes())
def test_generated_logs_as_lines(episodes: list[EpisodeInput]) -> None:
    assert check_lines(episodes) == len(episodes)
