"""`vge replay` of a run that recorded tokens and latency, with prices and completeness in its
run.json (PROTOCOL §1.4): the usage columns priced by the run, the same files with either
engine, the runs table's `complete` and `infrastructure_failures`, and a price that is not one
refused in one line naming run.json."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pyarrow.dataset as ds
import pyarrow.parquet as pq
import pytest

import replay
from vge_analytics.cli import main

DATA = Path(__file__).resolve().parents[2] / "data"
CASE = json.loads((DATA / "hand_worked" / "kettle_c_parse_multigoal_chain.json").read_text())


def _bench(root: Path) -> Path:
    bench = root / "bench"
    (bench / "ssm").mkdir(parents=True)
    shutil.copy(DATA / "kettle_ssm.json", bench / "ssm" / "kettle.json")
    (bench / "tasks.jsonl").write_text(json.dumps(CASE["task"]) + "\n")
    return bench


def _run(root: Path, name: str, meta: dict, usage: bool) -> Path:
    run = root / name
    run.mkdir()
    header = {"run_id": name, "model": "m", "agent_kind": "vlm", "meta": meta}
    (run / "run.json").write_text(json.dumps(header))
    steps = CASE["episode"]["steps"]
    if usage:  # step k: 1000 + k prompt tokens, 40 completion tokens, 0.5 s
        steps = [
            {**s, "prompt_tokens": 1000 + k, "completion_tokens": 40, "latency_seconds": 0.5}
            for k, s in enumerate(steps)
        ]
    (run / "episodes.jsonl").write_text(json.dumps({**CASE["episode"], "steps": steps}) + "\n")
    return run


def _table(out: Path, name: str):
    return ds.dataset(out / name, partitioning="hive").to_table().sort_by("run_id")


def test_usage_columns_and_completeness(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    bench = _bench(tmp_path)
    priced = _run(
        tmp_path,
        "priced",
        {
            "prompt_price_per_mtok": 2.5,
            "completion_price_per_mtok": 10,
            "complete": False,
            "infrastructure_failures": 3,
        },
        usage=True,
    )
    plain = _run(tmp_path, "plain", {"profile": "x"}, usage=False)
    files = {}
    for engine in ("reference", "kernel"):
        monkeypatch.setattr("replay.io._batch.KERNEL", engine == "kernel")
        out = tmp_path / engine
        replay.replay_runs([priced, plain], bench, out, progress=False)
        files[engine] = {str(p.relative_to(out)): p.read_bytes() for p in out.rglob("*.parquet")}
    assert files["reference"] == files["kernel"]

    out = tmp_path / "kernel"
    steps = _table(out, "steps").to_pylist()
    priced_steps = [s for s in steps if s["run_id"] == "priced"]
    # 8 steps; step k costs ((1000 + k) x 2.5 + 40 x 10) / 10^6 = (2900 + 2.5 k) / 10^6.
    assert [s["cost_usd"] for s in priced_steps] == [
        ((1000 + k) * 2.5 + 40 * 10.0) / 1e6 for k in range(8)
    ]
    assert priced_steps[3]["cost_usd"] == pytest.approx(0.0029075)
    assert {s["origin"] for s in steps} == {"agent"}
    assert all(
        s["cost_usd"] is None and s["latency_s"] is None for s in steps if s["run_id"] == "plain"
    )

    episodes = {e["run_id"]: e for e in _table(out, "episodes").to_pylist()}
    # 8028 prompt tokens (8 x 1000 + 0 + ... + 7), 320 completion, 4 s: 8028 x 2.5 + 3200 = 23270.
    e = episodes["priced"]
    assert (e["prompt_tokens"], e["completion_tokens"], e["latency_s"]) == (8028, 320, 4.0)
    assert e["cost_usd"] == pytest.approx(0.02327)
    assert sum(s["cost_usd"] for s in priced_steps) == pytest.approx(e["cost_usd"], abs=1e-15)
    assert episodes["plain"]["cost_usd"] is None and episodes["plain"]["prefix_steps"] is None

    runs = pq.read_table(out / "runs" / "runs.parquet").to_pylist()
    completeness = {r["run_id"]: (r["complete"], r["infrastructure_failures"]) for r in runs}
    assert completeness == {"plain": (None, None), "priced": (False, 3)}


@pytest.mark.parametrize("price", ["2.5", -1, True, 1e308, 1_000_001])
def test_a_price_that_is_not_one_stops_the_replay(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], price: object
) -> None:
    bench = _bench(tmp_path)
    run = _run(tmp_path, "bad", {"prompt_price_per_mtok": price}, usage=True)
    code = main(["replay", str(run), "--bench", str(bench), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip()
    assert code == 1 and "\n" not in err
    assert str(run / "run.json") in err
    assert (
        f"meta.prompt_price_per_mtok must be a number of USD from 0 to 1,000,000, not {price!r}"
        in err
    )


@pytest.mark.parametrize(
    ("field", "value"),
    [("prompt_tokens", -1), ("completion_tokens", 2**40 + 1), ("latency_seconds", -0.5)],
)
def test_a_count_out_of_bounds_is_an_invalid_record(
    tmp_path: Path, field: str, value: float
) -> None:
    """PROTOCOL §1.4: token counts from 0 to 2^40, latencies of at least 0 seconds."""
    bench = _bench(tmp_path)
    run = _run(tmp_path, "odd", {}, usage=True)
    line = json.loads((run / "episodes.jsonl").read_text())
    line["steps"][2][field] = value
    (run / "episodes.jsonl").write_text(json.dumps(line) + "\n")
    manifest = replay.replay_runs([run], bench, tmp_path / "out", progress=False)
    assert manifest.run("odd").quarantine == {"invalid_record": 1}
    (record,) = [
        json.loads(x) for x in (tmp_path / "out" / "quarantine.jsonl").read_text().splitlines()
    ]
    assert f"$.steps[2].{field}" in record["reason"]
