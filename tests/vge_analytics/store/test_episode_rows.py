"""A count's terms per (run, episode) as a projection of the episodes table
(`store._episode_rows`): the same rows, bits, types and order as the grouped and joined
query (`_episode_terms._grouped`), on the sample, on tables hypothesis makes (nulls in the
conditions, episodes out of order), and the grouped query where the projection cannot hold
(a repeated episode, a column of another type)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import polars as pl
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import vge_analytics as va
from replay.io import METRIC_CACHE_DIR
from tests.vge_analytics.store.kept import copy_out
from vge_analytics.store import _episode_rows, _episode_terms


@dataclass(frozen=True)
class Count:
    """A ratio of the episodes grain (as a metric file defines one)."""

    name: str
    numerator: str
    denominator: str
    grain: str = "episodes"
    scale: float = 100.0


COUNTS = (
    Count("SRx", "count(*) FILTER (WHERE success)", "count(*)"),
    Count("Rec", "count(*) FILTER (WHERE continued AND NOT source_success)", "count()"),
    Count("Nul", "count(*) FILTER (WHERE fixed IS NULL OR n_goals > 2)", "count(*) -- all\n"),
    Count("Neg", "count(*) FILTER (WHERE NOT continued)", "count(*) FILTER (WHERE g.fixed)"),
)

WIDE = Count("Txt", "count(*) FILTER (WHERE category LIKE 'M%' AND len(goals) > 1)", "count(*)")
"""A count whose condition reads a text and a list: grouped (DuckDB streams them)."""


def test_counts_are_projected_and_nothing_else():
    sr = va.MetricSet.builtin().get("SR")
    assert _episode_rows.count_terms(sr) == (
        "CAST(CASE WHEN (success) THEN 1 ELSE 0 END AS BIGINT)",
        "CAST(1 AS BIGINT)",
        frozenset({"success"}),
    )
    builtin = va.MetricSet.builtin()
    projected = [
        m.name for m in builtin.resolve(list(builtin.metrics)) if _episode_rows.count_terms(m)
    ]
    assert projected == ["SR", "RecoveryRate"]  # the other terms are sums or over steps
    for numerator in (
        "count(success)",  # null or not: another rule
        "count(DISTINCT success)",
        "sum(CAST(success AS INTEGER))",
        "count(*) + 0",
        "count(*) FILTER (WHERE success IN (SELECT true))",
        "count(*) FILTER (WHERE COLUMNS('succ.*'))",
        "count(*) FILTER (WHERE success = ?)",
        "count(*) FILTER (WHERE sum(n_goals) OVER () > 1)",
        "count(*) ORDER BY success",
        "main.count_star()",
        "count(*) FILTER (WHERE success",  # does not parse
    ):
        assert _episode_rows.count_terms(Count("X", numerator, "count(*)")) is None, numerator
    assert _episode_rows.count_terms(Count("X", "count(*)", "count(*)", grain="steps")) is None


def _both(store, ratio, runs=None) -> tuple[pl.DataFrame | None, pl.DataFrame]:
    held = _episode_terms._held(store)
    projected = _episode_rows.projected_terms(store, ratio, held, (), runs)
    return projected, _episode_terms._grouped(store, ratio, held, (), runs)


def _same(projected: pl.DataFrame | None, grouped: pl.DataFrame) -> None:
    assert projected is not None
    assert projected.schema == grouped.schema
    assert projected.equals(grouped)  # the same rows, bits and order


def test_the_projection_is_the_grouped_query_on_the_sample(sample_out: Path):
    store = va.open_store(sample_out)
    runs = [r["run_id"] for r in store.manifest["runs"]]
    ratios = [va.MetricSet.builtin().get(n) for n in ("SR", "RecoveryRate")] + list(COUNTS)
    for ratio in ratios:
        _same(*_both(store, ratio))
        for run in runs:  # a part of one run, as `_run_parts` makes them
            _same(*_both(store, ratio, [run]))
        _same(*_both(store, ratio, runs[1:3]))


def _rewrite(out: Path, run: str, change) -> None:
    """Rewrite the episodes file of `run` in `out` with `change(frame)`."""
    (part,) = sorted((out / "episodes" / f"run_id={run}").glob("*.parquet"))
    frame = pl.read_parquet(part)
    change(frame).write_parquet(part)


@st.composite
def _episodes(draw, base: pl.DataFrame) -> pl.DataFrame:
    """`base`'s rows in another order, their conditions' columns drawn (nulls included)."""
    n = base.height
    order = draw(st.permutations(range(n)))
    maybe = st.none() | st.booleans()
    return base[list(order)].with_columns(
        pl.Series("success", draw(st.lists(st.booleans(), min_size=n, max_size=n))),
        pl.Series("continued", draw(st.lists(maybe, min_size=n, max_size=n)), pl.Boolean),
        pl.Series("source_success", draw(st.lists(maybe, min_size=n, max_size=n)), pl.Boolean),
        pl.Series("fixed", draw(st.lists(maybe, min_size=n, max_size=n)), pl.Boolean),
        pl.Series("n_goals", draw(st.lists(st.integers(1, 4), min_size=n, max_size=n)), pl.Int64),
    )


@pytest.fixture(scope="module")
def drawn_out(pair_out: Path, tmp_path_factory) -> Path:
    return copy_out(pair_out, tmp_path_factory.mktemp("drawn") / "out")


@settings(
    max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(data=st.data())
def test_the_projection_is_the_grouped_query_on_drawn_tables(drawn_out: Path, data):
    for run in ("A", "B"):
        (part,) = sorted((drawn_out / "episodes" / f"run_id={run}").glob("*.parquet"))
        base = pl.read_parquet(part)
        data.draw(_episodes(base)).write_parquet(part)
    va.clear_cache()
    store = va.open_store(drawn_out)
    for ratio in COUNTS:
        for runs in (None, ["A"], ["B"], ["A", "B"]):
            _same(*_both(store, ratio, runs))


def test_a_repeated_episode_is_grouped(pair_out: Path, tmp_path: Path):
    """An episode twice in a run (a table edited by hand; the replay quarantines it): the
    projection gives way, and the kept rows are the grouped query's."""
    out = copy_out(pair_out, tmp_path / "out")
    _rewrite(out, "A", lambda frame: pl.concat([frame, frame.head(1)]))
    store = va.open_store(out)
    sr = va.MetricSet.builtin().get("SR")
    projected, grouped = _both(store, sr)
    assert projected is None
    assert grouped.filter(pl.col("episode_id") == "ep00")["SR:den"].to_list() == [2, 2, 1]
    held = _episode_terms._held(store)
    assert _episode_terms._compute(store, sr, held, (), ["A", "B"]).equals(grouped)


def test_a_column_of_another_type_is_grouped(pair_out: Path, tmp_path: Path):
    out = copy_out(pair_out, tmp_path / "out")
    _rewrite(out, "B", lambda frame: frame.with_columns(pl.col("n_goals").cast(pl.Int32)))
    store = va.open_store(out)
    projected, grouped = _both(store, va.MetricSet.builtin().get("SR"))
    assert projected is None and grouped.height == 21


def test_a_condition_on_a_text_or_a_list_is_grouped(pair_out: Path):
    store = va.open_store(pair_out)
    assert _episode_rows.count_terms(WIDE) is not None
    projected, grouped = _both(store, WIDE)
    assert projected is None and grouped.height == 21


def test_a_condition_that_does_not_bind_is_grouped(pair_out: Path):
    store = va.open_store(pair_out)
    ratio = Count("X", "count(*) FILTER (WHERE no_such_column)", "count(*)")
    assert _episode_rows.count_terms(ratio) is not None  # a count, as far as its text says
    held = _episode_terms._held(store)
    assert _episode_rows.projected_terms(store, ratio, held, ()) is None
    with pytest.raises(va.QueryError):
        _episode_terms._grouped(store, ratio, held, ())


def test_vge_metrics_keeps_srs_terms_by_the_projection(pair_out: Path, tmp_path: Path, monkeypatch):
    """The first `vge metrics OUT` keeps SR's terms per episode without the grouped query
    (without its group-by and join), and the file holds the grouped query's rows."""
    out = copy_out(pair_out, tmp_path / "out")
    grouped = _episode_terms._grouped

    def refused(*args, **kwargs):
        raise AssertionError("the grouped query ran")

    monkeypatch.setattr(_episode_terms, "_grouped", refused)
    va.metrics(out, by="run_id")
    (path,) = (out / METRIC_CACHE_DIR).glob("terms_episodes-*.parquet")
    store = va.open_store(out)
    want = grouped(store, va.MetricSet.builtin().get("SR"), _episode_terms._held(store), ())
    kept = pl.read_parquet(path)
    assert kept.schema == want.schema and kept.equals(want) and kept.height == 21


def test_over_one_row_a_count_is_its_projection_and_a_sum_is_not_always_its_value():
    """Why only counts: over one row, DuckDB's `count(*) FILTER (WHERE c)` is the
    projection's 1 or 0 (c true, false or null) and a BIGINT as it; a sum of that row's
    integer is a HUGEINT, of -0.0 is 0.0, of null is null."""
    import math

    import duckdb

    sr = va.MetricSet.builtin().get("SR")
    numerator, denominator, _ = _episode_rows.count_terms(sr)
    with duckdb.connect() as con:
        for success in (True, False, None):
            row = "(SELECT CAST(? AS BOOLEAN) AS success) AS g"
            grouped = con.execute(
                f"SELECT count(*) FILTER (WHERE success), count(*) FROM {row}", [success]
            ).fetchall()
            projected = con.execute(
                f"SELECT {numerator}, {denominator}, typeof({numerator}) FROM {row}", [success]
            ).fetchall()
            assert projected == [(*grouped[0], "BIGINT")] == [(int(success is True), 1, "BIGINT")]
        ((total, kind, fsum),) = con.execute(
            "SELECT sum(x), typeof(sum(n)), fsum(x) FROM (SELECT CAST('-0.0' AS DOUBLE) AS x, "
            "CAST(1 AS BIGINT) AS n)"
        ).fetchall()
        assert math.copysign(1, total) == math.copysign(1, fsum) == 1.0  # -0.0 summed: 0.0
        assert kind == "HUGEINT"


def test_a_files_run_is_its_folders(pair_out: Path, tmp_path: Path):
    """A file of run A whose run_id column says B (edited by hand): DuckDB reads its rows
    as A's (the dataset's partition), and so does the projection."""
    out = copy_out(pair_out, tmp_path / "out")
    _rewrite(out, "A", lambda frame: frame.with_columns(pl.lit("B").alias("run_id")))
    store = va.open_store(out)
    sr = va.MetricSet.builtin().get("SR")
    for runs in (None, ["A"], ["A", "B"]):
        projected, grouped = _both(store, sr, runs)
        _same(projected, grouped)
    assert grouped["run_id"].to_list() == ["A"] * 10 + ["B"] * 11
