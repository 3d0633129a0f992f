"""The scored steps counted per run and kept beside OUT (`store._step_counts`,
docs/METRICS.md): the error shares, switch classes and clicked views they give are the
tables', the file is what answers, and a file that is not one of ours is counted again."""

from __future__ import annotations

from pathlib import Path

import polars as pl
import pytest

import vge_analytics as va
from tests.vge_analytics.store.kept import copy_out, kept_files, plants
from vge_analytics import dashboard as dash
from vge_analytics.dashboard import _grounding
from vge_analytics.reports import _taxonomy
from vge_analytics.store import _kept as kept_module
from vge_analytics.store import _scan_counts, _step_counts, open_store, run_query

CHOICES = (
    (("run_id", "model"), None),
    (("model",), {"category": ["Microwave", "AirFryer"]}),
    (("category",), {"run_id": ["sim-human", "sim-vlm-a"]}),
    (("agent_kind",), {"meta_history_length": ["0", "3"]}),
    (("meta_history_length", "model"), {"model": "sim-vlm-f"}),
    ((), None),
    (("run_id",), {"category": "Nothing here"}),
    (("device_id",), None),  # a column not counted: the tables answer
    (("run_id",), {"action_type": "click"}),  # idem
)


_copy = copy_out


def _kept(out: Path, part: str = "*") -> list[Path]:
    return kept_files(out, f"counts_{part}-*")


def _three(out: Path, by, where) -> tuple[pl.DataFrame, ...]:
    views = dash.interaction_views(out, where=where)
    return (
        va.error_distribution(out, by=by, where=where, labels=True),
        va.switch_classes(out, by=by, where=where),
        views,
    )


def _direct(out: Path, monkeypatch, by, where) -> tuple[pl.DataFrame, ...]:
    with monkeypatch.context() as patch:
        patch.setattr(_taxonomy, "counted_steps", lambda *a, **k: None)
        patch.setattr(_grounding, "counted_steps", lambda *a, **k: None)
        return _three(out, by, where)


def _same(got: tuple[pl.DataFrame, ...], want: tuple[pl.DataFrame, ...]) -> bool:
    return all(g.equals(w) and g.schema == w.schema for g, w in zip(got, want, strict=True))


def test_kept_counts_give_the_tables_values_on_the_sample(
    sample_out: Path, tmp_path: Path, monkeypatch
):
    out = _copy(sample_out, tmp_path / "out")
    for by, where in CHOICES:
        want = _direct(out, monkeypatch, by, where)
        assert _same(_three(out, by, where), want), (by, where)  # counts, then reads
        assert _same(_three(out, by, where), want), (by, where)
    assert [p.name.split("-")[0] for p in _kept(out)] == [
        "counts_errors",
        "counts_switches",
        "counts_views",
    ]
    assert va.error_distribution(out, by="run_id")["count"].sum() > 0


def test_a_second_grouping_reads_what_the_first_counted(
    pair_out: Path, tmp_path: Path, monkeypatch
):
    out = _copy(pair_out, tmp_path / "out")
    _three(out, ("run_id",), None)
    kept = _kept(out)
    calls = []
    for counter in ("run_query", "count_steps"):
        real = getattr(_step_counts, counter)
        monkeypatch.setattr(
            _step_counts, counter, lambda *a, real=real, **k: calls.append(1) or real(*a, **k)
        )
    _three(out, ("model",), {"run_id": "A"})
    assert calls == [] and _kept(out) == kept  # read, not counted again


def test_the_kept_file_is_what_answers(pair_out: Path, tmp_path: Path):
    out = _copy(pair_out, tmp_path / "out")
    before = va.error_distribution(out, by="run_id")
    (path,) = _kept(out)
    frame = pl.read_parquet(path)
    frame.with_columns(pl.col("scored") * 2).write_parquet(path)
    va.clear_cache()
    after = va.error_distribution(out, by="run_id")
    assert after["count"].to_list() == [2 * n for n in before["count"].to_list()]
    assert after["share"].to_list() == before["share"].to_list()


def test_another_content_of_out_counts_again(pair_out: Path, tmp_path: Path):
    out = _copy(pair_out, tmp_path / "out")
    va.error_distribution(out, by="run_id")
    (old,) = _kept(out)
    (part,) = sorted((out / "steps" / "run_id=A").glob("*.parquet"))
    frame = pl.read_parquet(part)
    frame.head(frame.height - 1).write_parquet(part)  # A's last step gone
    va.clear_cache()
    want = va.error_distribution(out, by="run_id")
    (new,) = _kept(out)
    assert new != old and not old.exists()
    steps = va.steps(out, where={"truncated": False, "run_id": "A"})
    errors = steps.filter(pl.col("error_type").is_not_null()).height
    assert want.filter(pl.col("run_id") == "A")["count"].sum() == errors


PLANTS, PLANT_IDS = plants("scored")


@pytest.mark.parametrize("plant", PLANTS, ids=PLANT_IDS)
def test_a_file_that_is_not_ours_is_counted_again(
    pair_out: Path, tmp_path: Path, monkeypatch, plant
):
    out = _copy(pair_out, tmp_path / "out")
    want = _direct(out, monkeypatch, ("run_id",), None)
    _three(out, ("run_id",), None)
    (path,) = _kept(out, "errors")
    plant(path, tmp_path)
    va.clear_cache()
    assert _same(_three(out, ("run_id",), None), want)
    assert path.is_file() and not path.is_symlink()  # written again, whole, in its place


def test_a_file_over_the_bound_is_not_read(pair_out: Path, tmp_path: Path, monkeypatch):
    out = _copy(pair_out, tmp_path / "out")
    want = va.error_distribution(out, by="run_id")
    (path,) = _kept(out)
    pl.read_parquet(path).with_columns(pl.col("scored") * 0).write_parquet(path)
    monkeypatch.setattr(_step_counts, "MAX_COUNTS_BYTES", 100)
    va.clear_cache()
    assert va.error_distribution(out, by="run_id").equals(want)


def test_nothing_is_kept_where_out_cannot_be_written(pair_out: Path, tmp_path: Path, monkeypatch):
    out = _copy(pair_out, tmp_path / "out")

    def refuse(*args, **kwargs):
        raise PermissionError(13, "Read-only file system")

    monkeypatch.setattr(kept_module, "atomic_file", refuse)
    want = _direct(out, monkeypatch, ("run_id", "model"), None)
    assert _same(_three(out, ("run_id", "model"), None), want)
    assert _kept(out) == []


def _both(out: Path, name: str) -> tuple[pl.DataFrame | None, pl.DataFrame]:
    """The counts `name` as polars counts them from the files, and as DuckDB's query does."""
    store = open_store(out)
    part = _step_counts.PARTS[name]
    sql, params = _step_counts._query(store, part)
    polars = _scan_counts.count_steps(store, part.keys, part.name, part.where, part.only)
    return polars, run_query(store, sql, params)


@pytest.mark.parametrize("chunk", [1, 3, _scan_counts.CHUNK_FILES])
@pytest.mark.parametrize("name", sorted(_step_counts.PARTS))
def test_the_files_counted_by_polars_are_the_tables_query(
    sample_out: Path, monkeypatch, name: str, chunk: int
):
    monkeypatch.setattr(_scan_counts, "CHUNK_FILES", chunk)  # one run a chunk, some, all
    polars, duckdb = _both(sample_out, name)
    assert polars is not None and polars.height > 0
    assert polars.equals(duckdb) and polars.schema == duckdb.schema


@pytest.mark.parametrize("chunk", [1, _scan_counts.CHUNK_FILES])
def test_a_files_run_is_its_folders_as_in_duckdb(
    pair_out: Path, tmp_path: Path, monkeypatch, chunk: int
):
    monkeypatch.setattr(_scan_counts, "CHUNK_FILES", chunk)
    out = _copy(pair_out, tmp_path / "out")
    (part,) = sorted((out / "steps" / "run_id=A").glob("*.parquet"))
    pl.read_parquet(part).with_columns(pl.lit("B").alias("run_id")).write_parquet(part)
    (part,) = sorted((out / "steps" / "run_id=B").glob("*.parquet"))
    pl.read_parquet(part).drop("run_id").write_parquet(part)
    va.clear_cache()
    for name in _step_counts.PARTS:
        polars, duckdb = _both(out, name)
        assert set(duckdb["run_id"]) == {"A", "B"}  # the runs of their folders, not the files'
        assert polars is not None and polars.equals(duckdb)


def test_files_polars_cannot_read_as_duckdb_does_are_counted_by_duckdb(
    pair_out: Path, tmp_path: Path, monkeypatch
):
    out = _copy(pair_out, tmp_path / "out=1")  # polars would read `out` as a column
    want = _direct(out, monkeypatch, ("run_id",), None)
    assert _both(out, "views")[0] is None
    assert _same(_three(out, ("run_id",), None), want)
    out = _copy(pair_out, tmp_path / "out")
    (part,) = sorted((out / "steps" / "run_id=B").glob("*.parquet"))
    pl.read_parquet(part).with_columns(pl.lit(None).alias("is_switch")).write_parquet(part)
    va.clear_cache()  # a column of nulls, as DuckDB unifies it: null booleans
    polars, duckdb = _both(out, "switches")
    assert polars is None or polars.equals(duckdb)
    assert _same(_three(out, ("run_id",), None), _direct(out, monkeypatch, ("run_id",), None))


def test_the_count_stops_past_the_time_limit_between_chunks(
    pair_out: Path, tmp_path: Path, monkeypatch
):
    out = _copy(pair_out, tmp_path / "out")
    monkeypatch.setattr(_scan_counts, "CHUNK_FILES", 1)  # A, then B
    # the count's end set 1000 s ago (here; the count's process looks at the real clock):
    # it counts A, then finds its time over before B (`test_scan_counts` for the order)
    monkeypatch.setattr(_scan_counts, "monotonic", lambda: -1000.0)
    with (
        va.query_limits(timeout=150),
        pytest.raises(va.QueryLimitError, match="time limit of 150 s"),
    ):
        va.error_distribution(out, by="run_id")
    assert _kept(out) == []  # nothing kept
