"""What the store builds when (`store._datasets`, docs/PERFORMANCE.md, Start-up): the runs
table read whole, as a dataset over its files would scan it; a table whose schema is kept
built only when a query of the analytics names it; the same catalogue either way."""

from __future__ import annotations

from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

import replay
import vge_analytics as va
from tests.vge_analytics.store.kept import copy_out
from vge_analytics.store import _datasets, _store, run_query

_copy = copy_out  # an OUT without its cache folder


def _built(store: _store.Store) -> list[str]:
    """The tables of `store` that are datasets now (a `Deferred` one built, or never one)."""
    return [
        name
        for name, source in store.sources.items()
        if not isinstance(source, _datasets.Deferred) or source.built
    ]


def test_the_runs_table_read_whole_is_the_datasets_table(tmp_path: Path):
    """Two files of runs/ with different columns: each column typed as the unified schema
    has it (int32 and int64 give int64), a column a file lacks null there, files in order."""
    folder = tmp_path / "runs"
    folder.mkdir()
    first = pa.table({"run_id": ["a", "b"], "n": pa.array([1, 2], pa.int32())})
    second = pa.table({"run_id": ["c"], "n": pa.array([3], pa.int64()), "x": ["only c"]})
    pq.write_table(first, folder / "1.parquet")
    pq.write_table(second, folder / "2.parquet")
    out = replay.location(str(tmp_path))
    files = [("runs/1.parquet", None), ("runs/2.parquet", None)]
    whole = _datasets._whole(out, files, None)
    scanned = _datasets._dataset(out, files).to_table()
    assert whole.equals(scanned) and whole.schema == scanned.schema
    assert whole.to_pydict() == {
        "run_id": ["a", "b", "c"],
        "n": [1, 2, 3],
        "x": [None, None, "only c"],
    }
    assert pa.types.is_dictionary(whole.schema.field("run_id").type)  # as the dataset reads it


def test_a_large_runs_table_is_scanned(tmp_path: Path, monkeypatch):
    (tmp_path / "runs").mkdir()
    pq.write_table(pa.table({"run_id": ["a"]}), tmp_path / "runs" / "1.parquet")
    out, files = replay.location(str(tmp_path)), [("runs/1.parquet", None)]
    monkeypatch.setattr(_datasets, "RUNS_IN_MEMORY", 0)
    assert _datasets._whole(out, files, None) is None


def test_a_kept_schema_defers_the_datasets_until_a_query_names_them(pair_out: Path, tmp_path: Path):
    out = _copy(pair_out, tmp_path / "out")
    cold = va.open_store(out)  # reads every footer, keeps the schemas
    assert _built(cold) == ["steps", "episodes", "goals", "runs"]
    want = va.metrics(out, by="run_id")  # and fills the metric cache
    va.clear_cache()
    warm = va.open_store(out)
    assert _built(warm) == ["runs"]
    assert warm.columns == cold.columns  # the catalogue, from the kept schemas
    assert va.metrics(out, by="run_id").equals(want)  # the cache answers: nothing built
    assert _built(warm) == ["runs"]
    got = run_query(warm, "SELECT count(*) AS n FROM Episodes", [])
    assert got["n"].to_list() == [21]  # 10 episodes of A, 11 of B
    assert _built(warm) == ["episodes", "runs"]
    # A user's query sees every table, whatever it names.
    assert va.sql(out, "SELECT count(*) AS n FROM runs")["n"].to_list() == [2]
    assert _built(warm) == ["steps", "episodes", "goals", "runs"]


def test_a_table_is_named_as_a_word():
    names = _store._names
    assert names("SELECT * FROM steps", "steps")
    assert names('SELECT * FROM "STEPS" s', "steps")
    assert names("FROM runs JOIN steps USING (run_id)", "steps")
    assert not names("SELECT sum(n) FROM __terms_steps", "steps")
    assert not names("SELECT n_steps, steps_total FROM runs", "steps")
    assert not names("SELECT $steps FROM runs", "steps")
