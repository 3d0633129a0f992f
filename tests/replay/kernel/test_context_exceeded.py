"""An episode line's `ended` (PROTOCOL §1.4): a log the harness ended because the model
refused the next request as longer than its context window. Both engines give such an
episode the termination `context_exceeded` when its log runs out before any other
termination (§3.5), change nothing else, and agree table for table (hand-picked logs and
the generated ones of `test_kernel`)."""

from __future__ import annotations

import json
from pathlib import Path

import msgspec
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import replay
from replay.kernel import EpisodeInput, replay_kernel

from .test_kernel import CASES, _episodes, check_batch, episode, machine_of


def _case(name: str) -> tuple[replay.Machine, replay.Task, list[dict], float]:
    doc = json.loads((CASES / f"{name}.json").read_text())
    machine = machine_of(CASES.parent / doc["ssm"], doc["device_id"])
    return (
        machine,
        msgspec.convert(doc["task"], replay.Task),
        doc["episode"]["steps"],
        doc["lambda"],
    )


def _ended(e: EpisodeInput) -> EpisodeInput:
    return e._replace(log=msgspec.structs.replace(e.log, ended="context_exceeded"))


def _episodes_table(batch: list[EpisodeInput]) -> pa.Table:
    check_batch(batch)  # the kernel's tables are the reference's
    return replay_kernel(batch, run_id="run", model="model", agent_kind="vlm").episodes


def test_a_log_that_runs_out_ends_as_context_exceeded_and_nothing_else_changes() -> None:
    # kettle_e: 5 steps, goal 1 of 2 completed, budgets left (2 of 6 global): `log_ended`.
    machine, task, steps, lam = _case("kettle_e_log_ended")
    plain = episode(machine, task, steps, lam)
    table = _episodes_table([plain, _ended(plain)])
    assert table["termination"].to_pylist() == ["log_ended", "context_exceeded"]
    assert table["success"].to_pylist() == [False, False]
    assert table["goals_completed"].to_pylist() == [1, 1]
    assert table["spl"].to_pylist() == [0.0, 0.0]
    assert table["n_steps"].to_pylist() == [5, 5]
    # Every other column is the same: the ending is the only thing `ended` decides.
    rest = [c for c in table.column_names if c != "termination"]
    assert table.select(rest).slice(0, 1).equals(table.select(rest).slice(1, 1))
    # The reference engine says the same, row for row.
    ref = replay.replay_episode(
        machine, task, _ended(plain).log, lam=lam, run_id="r", model="m", agent_kind="vlm"
    )
    assert (ref.episode.termination, ref.episode.truncated_steps) == ("context_exceeded", 0)


@pytest.mark.parametrize(
    ("name", "termination", "truncated"),
    [
        ("kettle_c_parse_multigoal_chain", "success", 0),
        ("kettle_d_local_budget", "budget_local", 2),
        ("kettle_b_danger_repetitive_budget", "budget_global", 2),
    ],
)
def test_a_termination_within_the_log_wins(name: str, termination: str, truncated: int) -> None:
    """The refusal came after the steps of the log; a termination the steps reached is the
    episode's, and steps logged after it are truncated as before."""
    machine, task, steps, lam = _case(name)
    table = _episodes_table([_ended(episode(machine, task, steps, lam))])
    assert table["termination"].to_pylist() == [termination]
    assert table["truncated_steps"].to_pylist() == [truncated]


def test_a_refusal_before_the_first_step() -> None:
    """The first request was already too long: no step, the episode failed."""
    machine, task, _, lam = _case("kettle_c_parse_multigoal_chain")
    table = _episodes_table([_ended(episode(machine, task, [], lam))])
    row = table.to_pylist()[0]
    assert (row["termination"], row["n_steps"], row["L_act"], row["success"]) == (
        "context_exceeded", 0, 0, False,
    )  # fmt: skip
    assert (row["goals_completed"], row["spl"]) == (0, 0.0)


def test_the_line_reads_ended() -> None:
    line = b'{"episode_id":"e","steps":[],"ended":"context_exceeded"}'
    log = msgspec.json.decode(line, type=replay.EpisodeLog)
    assert log.ended == "context_exceeded"
    assert (
        msgspec.json.decode(b'{"episode_id":"e","steps":[]}', type=replay.EpisodeLog).ended is None
    )
    with pytest.raises(
        msgspec.ValidationError, match=r"Invalid enum value 'bored' - at `\$.ended`"
    ):
        msgspec.json.decode(b'{"episode_id":"e","ended":"bored"}', type=replay.EpisodeLog)


@st.composite
def _some_ended(draw) -> list[EpisodeInput]:
    """The generated logs of `test_kernel`, each cut short at a random step (a refusal can
    come at any step) and given `ended` or not."""
    out = []
    for e in draw(_episodes()):
        cut = draw(st.integers(0, len(e.log.steps)))
        e = e._replace(log=msgspec.structs.replace(e.log, steps=e.log.steps[:cut]))
        out.append(_ended(e) if draw(st.sampled_from([True, True, False])) else e)
    return out


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_some_ended())
def test_generated_logs_some_ended(episodes: list[EpisodeInput]) -> None:
    check_batch(episodes)
    ref = [
        replay.replay_episode(
            e.machine, e.task, e.log, lam=e.lam, run_id="r", model="m", agent_kind="vlm"
        ).episode
        for e in episodes
    ]
    for e, row in zip(episodes, ref, strict=True):
        plain = replay.replay_episode(
            e.machine,
            e.task,
            msgspec.structs.replace(e.log, ended=None),
            lam=e.lam,
            run_id="r",
            model="m",
            agent_kind="vlm",
        ).episode
        want = "context_exceeded" if e.log.ended and plain.termination == "log_ended" else None
        assert row.termination == (want or plain.termination)
        assert msgspec.structs.replace(row, termination=plain.termination) == plain


def test_a_line_with_another_ending_is_quarantined(tmp_path: Path) -> None:
    """`ended` takes the one value: anything else is not an episode record (PROTOCOL §7.6)."""
    _, task, steps, _ = _case("kettle_e_log_ended")
    bench = tmp_path / "bench"
    (bench / "ssm").mkdir(parents=True)
    (bench / "ssm" / "kettle.json").write_text((CASES.parent / "kettle_ssm.json").read_text())
    tasks = [{**msgspec.to_builtins(task), "episode_id": e} for e in ("a", "b", "c")]
    (bench / "tasks.jsonl").write_text("".join(json.dumps(t) + "\n" for t in tasks))
    run = tmp_path / "run"
    run.mkdir()
    (run / "run.json").write_text(json.dumps({"run_id": "r", "model": "m", "agent_kind": "vlm"}))
    lines = [
        {"episode_id": "a", "steps": steps, "ended": "context_exceeded"},
        {"episode_id": "b", "steps": steps, "ended": "bored"},
        {"episode_id": "c", "steps": steps},
    ]
    (run / "episodes.jsonl").write_text("".join(json.dumps(x) + "\n" for x in lines))
    out = tmp_path / "out"
    manifest = replay.replay_runs([run], bench, out, progress=False)
    assert (manifest.run("r").counts.replayed, manifest.run("r").counts.quarantined) == (2, 1)
    (record,) = [json.loads(x) for x in (out / "quarantine.jsonl").read_text().splitlines()]
    assert (record["episode_id"], record["kind"], record["line"]) == ("b", "invalid_record", 2)
    assert "ended" in record["reason"]
    episodes = pq.read_table(out / "episodes", partitioning=None).sort_by("episode_id")
    assert episodes["episode_id"].to_pylist() == ["a", "c"]
    assert episodes["termination"].to_pylist() == ["context_exceeded", "log_ended"]
