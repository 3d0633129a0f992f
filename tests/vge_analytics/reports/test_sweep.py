"""`sweep`: SR/SSR by lambda from re-replays, monotone in lambda, refusals.

Every episode of the hand runs has a task lambda (its recorded budget). Sweeping to a lambda
above it is allowed when the logs hold the steps: kettle_c/f/g and all oven cases succeed
within their logs, kettle_e's log ends before its budget (log_ended), and kettle_b/d hit
their budget at lambda 3 but have steps logged after it (truncated at 3) that reach success
at larger lambdas. The `cut` run below has an episode whose log stops exactly at its budget.
"""

from __future__ import annotations

import json
from pathlib import Path

import polars as pl
import pytest

import replay
import vge_analytics as va

from ..conftest import _case, replay_to, write_bench, write_run


def test_sweep_is_monotone_and_gains(hand_out: Path) -> None:
    df = va.sweep(hand_out, [1, 2, 3, 4, 5, 8])
    assert df.columns == [
        "run_id", "model", "lambda",
        "SR", "SR_gain", "SR_rel_gain", "SSR", "SSR_gain", "SSR_rel_gain",
    ]  # fmt: skip
    for run in ("kettle-vlm", "oven-human"):
        part = df.filter(pl.col("run_id") == run).sort("lambda")
        assert part["lambda"].to_list() == [1.0, 2.0, 3.0, 4.0, 5.0, 8.0]
        for col in ("SR", "SSR"):
            values = part[col].to_list()
            assert values == sorted(values), (run, col, values)
            base = values[0]
            assert part[f"{col}_gain"].to_list() == pytest.approx([v - base for v in values])
    oven = df.filter(pl.col("run_id") == "oven-human").sort("lambda")
    # Every oven episode succeeds at its own lambda (<= 8), so at 8 all five do.
    assert oven["SR"].to_list()[-1] == 100.0
    # At lambda 1 none succeeds (SR 0): relative gains over 0 are undefined -> null.
    assert oven["SR"].to_list()[0] == 0.0 and oven["SR_rel_gain"].null_count() == 6


def test_sweep_at_recorded_lambdas_matches_the_replay(hand_out: Path) -> None:
    # oven-human episodes recorded lambdas 5, 5, 4, 8, 3: at lambda 8 the replay equals OUT
    # for every episode except none (all succeed) -> SR 100 as in `metrics`.
    sw = va.sweep(hand_out, [8], runs=["oven-human"])
    m = va.metrics(hand_out, where={"run_id": "oven-human"}, metrics=["SR", "SSR"])
    assert sw["SR"].to_list() == m["SR"].to_list() == [100.0]


@pytest.fixture(scope="module")
def cut_out(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("cut")
    b = _case("kettle_b_danger_repetitive_budget")  # task lambda 3: B_global = 6
    c = _case("kettle_c_parse_multigoal_chain")  # task lambda 2, succeeds
    bench = write_bench(root, [b, c])
    cut = dict(b["episode"], steps=b["episode"]["steps"][:6])  # nothing after the budget
    run = write_run(root, {"run_id": "cut", "model": "m", "agent_kind": "vlm"}, [cut, c["episode"]])
    return replay_to(root / "out", [run], bench)


def test_sweep_refuses_a_lambda_the_logs_cannot_support(cut_out: Path) -> None:
    ok = va.sweep(cut_out, "2,3")
    assert ok["SR"].to_list() == [50.0, 50.0]
    with pytest.raises(va.SweepRefused) as info:
        va.sweep(cut_out, "2,4")
    message = str(info.value)
    assert "\n" not in message
    assert "run cut" in message and "lambda 4" in message and "hw_kettle_b" in message


def test_sweep_inputs(hand_out: Path, tmp_path: Path) -> None:
    with pytest.raises(va.UnknownMetricError):
        va.sweep(hand_out, "2", metrics=["nope"])
    with pytest.raises(replay.ConfigError, match="episode rows only"):
        va.sweep(hand_out, "2", metrics=["EIR"])
    with pytest.raises(va.UnknownRunError):
        va.sweep(hand_out, "2", runs=["nope"])
    for bad in ("", "0", "x", "-1"):
        with pytest.raises(replay.ConfigError):
            va.sweep(hand_out, bad)
    assert va.parse_lambdas("5, 2,3,2") == [2.0, 3.0, 5.0]
    # A manifest pointing at inputs that are gone: a clear error, not a traceback.
    copy = tmp_path / "out"
    import shutil

    shutil.copytree(hand_out, copy)
    manifest = json.loads((copy / "manifest.json").read_text())
    for entry in manifest["runs"]:
        entry["inputs"]["episodes"]["path"] = str(tmp_path / "gone.jsonl")
    (copy / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(va.SweepInputError, match="not found"):
        va.sweep(copy, "2")


def test_sweep_refuses_changed_inputs(tmp_path: Path) -> None:
    c = _case("kettle_c_parse_multigoal_chain")
    bench = write_bench(tmp_path, [c])
    run = write_run(tmp_path, {"run_id": "r", "model": "m", "agent_kind": "vlm"}, [c["episode"]])
    out = replay_to(tmp_path / "out", [run], bench)
    assert va.sweep(out, "2")["SR"].to_list() == [100.0]
    short = dict(c["episode"], steps=c["episode"]["steps"][:2])
    (run / "episodes.jsonl").write_text(json.dumps(short) + "\n")
    with pytest.raises(va.SweepInputError, match="changed since OUT was replayed"):
        va.sweep(out, "2")


def test_sweep_finds_inputs_next_to_out_from_another_directory(tmp_path, monkeypatch) -> None:
    """The manifest keeps input paths as given; a sweep run elsewhere finds them beside OUT."""
    import shutil

    from replay import replay_runs
    from vge_analytics import sweep

    logs = Path(__file__).resolve().parents[3] / "logs"
    work = tmp_path / "work"
    shutil.copytree(logs / "bench", work / "bench")
    shutil.copytree(logs / "runs" / "sim-human", work / "runs" / "sim-human")
    monkeypatch.chdir(work)
    replay_runs(["runs/sim-human"], "bench", "out", progress=False)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    table = sweep(work / "out", lambdas=[2, 5])
    # The logs read are the ones replayed: no task of the sample has its own lambda, so at
    # the run's lambda 5 the sweep gives the SR that `metrics` reads from OUT ...
    assert table["lambda"].to_list() == [2.0, 5.0]
    assert table["SR"][1] == va.metrics(work / "out", metrics=["SR"])["SR"][0]
    # ... and at every lambda what the same sweep gives run from where the paths were given.
    monkeypatch.chdir(work)
    assert table.equals(sweep("out", lambdas=[2, 5]))
