"""`replay_runs` on the hand-worked sample: layout, readers, counts, rows, manifest, runs."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import duckdb
import msgspec
import pandas as pd
import polars as pl
import pyarrow.dataset as ds
import pyarrow.parquet as pq
import pytest

import replay
from replay.io import episode_decoder

from ..conftest import COPIES, Sample


def test_layout(replayed, sample: Sample) -> None:
    out, manifest = replayed
    for table in ("steps", "episodes", "goals"):
        for run_id in ("human-1", "vlm-a"):
            assert (out / table / f"run_id={run_id}" / "part-00000.parquet").is_file()
    assert (out / "runs" / "runs.parquet").is_file()
    assert (out / "quarantine.jsonl").read_bytes() == b""
    assert json.loads((out / "manifest.json").read_text())["engine_version"] == (
        replay.ENGINE_VERSION
    )
    visible = [p for p in out.rglob("*") if ".replay" not in p.parts]
    assert not [p for p in visible if p.name.endswith(".tmp")]
    assert manifest.exit_code == 0
    assert manifest.requested == ["human-1", "vlm-a"]
    assert manifest.replayed == ["human-1", "vlm-a"] and manifest.skipped == []


def test_counts_add_up(replayed, sample: Sample) -> None:
    out, manifest = replayed
    vlm = manifest.run("vlm-a")
    c = vlm.counts
    assert c.lines_read == c.replayed + c.quarantined == len(sample.episode_ids)
    assert c.steps == sum(sample.steps_per_episode.values())
    human = manifest.run("human-1").counts
    assert human.lines_read == human.replayed == len(sample.episode_ids) // COPIES
    t = manifest.content.totals
    assert t.lines_read == c.lines_read + human.lines_read
    assert t.steps == c.steps + human.steps
    steps = pq.read_table(out / "steps" / "run_id=vlm-a", partitioning=None)
    assert steps.num_rows == c.steps
    assert sum(steps["truncated"].to_pylist()) == c.truncated_steps > 0


@pytest.mark.parametrize("table", ["steps", "episodes", "goals"])
def test_four_readers_agree(replayed, table: str) -> None:
    out, manifest = replayed
    glob = str(out / table / "**" / "*.parquet")
    con = duckdb.connect()
    by_duckdb = dict(
        con.execute(
            "SELECT run_id, count(*) FROM read_parquet(?, hive_partitioning = true) GROUP BY 1",
            [glob],
        ).fetchall()
    )
    by_polars = dict(
        pl.read_parquet(glob, hive_partitioning=True).group_by("run_id").len().iter_rows()
    )
    by_pyarrow_ds = ds.dataset(out / table, format="parquet", partitioning="hive").to_table()
    by_pyarrow = pq.read_table(out / table, partitioning=None)
    by_pandas = pd.read_parquet(out / table, partitioning=None)
    assert by_duckdb == by_polars
    assert sum(by_duckdb.values()) == by_pyarrow.num_rows == by_pyarrow_ds.num_rows
    assert len(by_pandas) == by_pyarrow.num_rows
    assert by_pandas["run_id"].value_counts().to_dict() == by_duckdb
    assert by_pyarrow.schema.field("run_id").type == "string"
    if table == "steps":
        assert by_duckdb == {r: manifest.run(r).counts.steps for r in by_duckdb}


def test_rows_equal_direct_replay(replayed, sample: Sample) -> None:
    """The tables hold exactly what `replay_episode` gives, in file order."""
    out, _ = replayed
    bench = replay.Benchmark.open(sample.bench)
    lines = (sample.vlm / "episodes.jsonl").read_bytes().splitlines()
    episodes = pq.read_table(out / "episodes" / "run_id=vlm-a", partitioning=None)
    assert episodes["episode_id"].to_pylist() == sample.episode_ids
    steps = pq.read_table(out / "steps" / "run_id=vlm-a", partitioning=None).to_pylist()
    goals = pq.read_table(out / "goals" / "run_id=vlm-a", partitioning=None).to_pylist()
    want_steps, want_goals = [], []
    for line in lines:
        log = episode_decoder.decode(line)
        task = bench.tasks[log.episode_id].task
        result = replay.replay_episode(
            bench.machine(task.device_id),
            task,
            log,
            lam=task.lam if task.lam is not None else 5.0,
            run_id="vlm-a",
            model="model-a",
            agent_kind="vlm",
        )
        want_steps += [msgspec.to_builtins(r) for r in result.steps]
        want_goals += [msgspec.to_builtins(r) for r in result.goals]
    assert steps == want_steps
    assert goals == want_goals


def test_divergence_summary(replayed, sample: Sample) -> None:
    out, manifest = replayed
    n_cases = len(sample.episode_ids) // COPIES
    d = manifest.run("vlm-a").divergence
    assert d.by_field == {"feedback": 0, "state": n_cases, "view": 0}
    assert d.steps_diverged == d.episodes_diverged == n_cases
    assert d.steps_compared > n_cases
    assert manifest.run("vlm-a").counts.diverged_steps == n_cases
    assert manifest.run("human-1").divergence.steps_compared == 0
    rows = duckdb.sql(
        f"SELECT episode_id, step, diverged_fields FROM read_parquet('{out}/steps/**/*.parquet')"
        " WHERE diverged"
    ).fetchall()
    assert len(rows) == n_cases
    assert all(eid.endswith("-c2") and step == 0 and f == ["state"] for eid, step, f in rows)


def test_runs_table(replayed) -> None:
    out, _ = replayed
    runs = pq.read_table(out / "runs" / "runs.parquet")
    rows = {r["run_id"]: r for r in runs.to_pylist()}
    assert runs.column_names[:4] == ["run_id", "model", "agent_kind", "lambda"]
    assert list(rows) == ["human-1", "vlm-a"]
    vlm, human = rows["vlm-a"], rows["human-1"]
    assert (vlm["model"], vlm["agent_kind"], vlm["lambda"]) == ("model-a", "vlm", 5.0)
    assert (human["lambda"], human["lambda_run"]) == (5.0, None)
    # scalars become columns; mixed types become text; nested values stay in `meta` only
    assert runs.schema.field("meta_history").type == "string"
    assert (vlm["meta_history"], human["meta_history"]) == ("3", "full")
    assert runs.schema.field("meta_participants").type == "int64"
    assert (vlm["meta_participants"], human["meta_participants"]) == (None, 7)
    assert runs.schema.field("meta_trained").type == "bool"
    assert "meta_notes" not in runs.column_names
    assert json.loads(vlm["meta"])["notes"] == {"x": 1}


def test_manifest_records_inputs(replayed, sample: Sample) -> None:
    out, manifest = replayed
    vlm = manifest.run("vlm-a")
    assert vlm.inputs.run_dir == str(sample.vlm)
    assert vlm.inputs.episodes.path == str(sample.vlm / "episodes.jsonl")
    assert manifest.run("human-1").inputs.episodes.path.endswith("episodes.jsonl.gz")
    assert set(vlm.inputs.ssm) == {p.stem for p in (sample.bench / "ssm").glob("*.json")}
    for name, ref in vlm.inputs.ssm.items():  # each file's own digest
        assert ref.path == str(sample.bench / "ssm" / f"{name}.json")
        assert ref.sha256 == hashlib.sha256(Path(ref.path).read_bytes()).hexdigest(), name
    assert (
        vlm.inputs.episodes.sha256
        == hashlib.sha256((sample.vlm / "episodes.jsonl").read_bytes()).hexdigest()
    )
    text = (out / "manifest.json").read_text()
    assert replay.read_manifest(out) == manifest.content
    for clock_word in ("time", "date", "elapsed"):
        assert clock_word not in text.replace("timestamp", "")


def test_lambda_precedence(copy_sample: Sample, tmp_path: Path) -> None:
    """--lambda > task lambda > run.json lambda > 5."""
    s = copy_sample
    tasks = [json.loads(line) for line in (s.bench / "tasks.jsonl").read_text().splitlines()]
    task_lam = {t["episode_id"]: t["lambda"] for t in tasks}
    out = tmp_path / "out"
    replay.replay_runs([s.vlm], s.bench, out, progress=False)
    eps = pq.read_table(out / "episodes", partitioning=None).to_pylist()
    assert {e["episode_id"]: e["lambda"] for e in eps} == {
        e["episode_id"]: float(task_lam[e["episode_id"]]) for e in eps
    }
    replay.replay_runs([s.vlm], s.bench, out, lam=7, progress=False)
    eps = pq.read_table(out / "episodes", partitioning=None).to_pylist()
    assert {e["lambda"] for e in eps} == {7.0}
    for t in tasks:
        t.pop("lambda")
    (s.bench / "tasks.jsonl").write_text("".join(json.dumps(t) + "\n" for t in tasks))
    replay.replay_runs([s.vlm, s.human], s.bench, out, progress=False)
    eps = pq.read_table(out / "episodes", partitioning=None).to_pylist()
    by_run = {(e["run_id"], e["lambda"]) for e in eps}
    assert by_run == {("vlm-a", 5.0), ("human-1", 5.0)}
    run_json = json.loads((s.vlm / "run.json").read_text())
    (s.vlm / "run.json").write_text(json.dumps({**run_json, "lambda": 2.5}))
    replay.replay_runs([s.vlm], s.bench, out, progress=False)
    eps = pq.read_table(out / "episodes" / "run_id=vlm-a", partitioning=None)
    assert set(eps["lambda"].to_pylist()) == {2.5}
    assert pq.read_table(out / "runs" / "runs.parquet").to_pylist()[1]["lambda"] == 2.5


def test_smaller_lambda_truncates_earlier(sample: Sample, tmp_path: Path) -> None:
    small = replay.replay_runs([sample.vlm], sample.bench, tmp_path / "a", lam=1, progress=False)
    large = replay.replay_runs([sample.vlm], sample.bench, tmp_path / "b", lam=10, progress=False)
    assert small.run("vlm-a").counts.steps == large.run("vlm-a").counts.steps
    assert small.run("vlm-a").counts.truncated_steps > large.run("vlm-a").counts.truncated_steps

    def episodes(out: Path) -> dict[str, dict]:
        rows = pq.read_table(out / "episodes", partitioning=None).to_pylist()
        return {r["episode_id"]: r for r in rows}

    a, b = episodes(tmp_path / "a"), episodes(tmp_path / "b")
    for eid, ep in a.items():
        assert ep["n_steps"] == b[eid]["n_steps"] == sample.steps_per_episode[eid]
        assert ep["L_act"] <= b[eid]["L_act"]
        assert ep["truncated_steps"] >= b[eid]["truncated_steps"]
        assert ep["L_act"] + ep["truncated_steps"] == ep["n_steps"]
        assert ep["budget_global"] == 1.0 * ep["L_opt"]
    steps = pq.read_table(tmp_path / "a" / "steps", partitioning=None)
    per_episode = steps.group_by("episode_id").aggregate([("step", "max"), ("step", "count")])
    for eid, top, count in zip(*per_episode.to_pydict().values(), strict=True):
        assert count == top + 1 == sample.steps_per_episode[eid]  # never invents steps
