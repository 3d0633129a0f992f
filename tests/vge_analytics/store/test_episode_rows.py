"""A count's or a sum's terms per (run, episode) as a projection of the episodes table
(`store._episode_rows`): the same rows, bits, types and order as the grouped and joined
query (`_episode_terms._grouped`), on the sample, on tables hypothesis makes (nulls in the
conditions and the values, -0.0, NaN, infinities, large integers, episodes out of order),
and the grouped query where the projection cannot hold (a repeated episode, a column of
another type, another aggregate)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
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

SUMS = (
    Count("Fs", "fsum(vsps)", "count(*)"),
    Count("Ks", "kahan_sum(cost_usd) FILTER (WHERE continued)", "sum(n_switches)"),
    Count("Ss", "SUM(vsps)", "sumkahan(-cost_usd) FILTER (WHERE fixed IS NULL)"),
    Count(
        "Si", "sum(n_switches) FILTER (WHERE NOT continued)", "sum(CAST(n_goals AS DECIMAL(10, 2)))"
    ),
    Count("Sb", "sum(prefix_steps) FILTER (WHERE g.fixed)", "sum(fixed)"),
    Count("Sf", "fsum(CAST(latency_s AS FLOAT) * 2)", "sum(CAST(prefix_steps AS UTINYINT))"),
)
"""Sums of numbers over the episodes (doubles, floats, integers, decimals, booleans), with
and without a filter: projected (`list_aggregate` over the row's value)."""

BUILTIN = ("SR", "SSR", "SPL", "VSPS", "GVPE", "RecoveryRate", "StepsToRecover")
"""The built-in metrics of the episodes projected (State-F1's sum reads lists: grouped)."""

WIDE = Count("Txt", "count(*) FILTER (WHERE category LIKE 'M%' AND len(goals) > 1)", "count(*)")
"""A count whose condition reads a text and a list: grouped (DuckDB streams them)."""


def test_counts_are_projected_and_nothing_else():
    sr = va.MetricSet.builtin().get("SR")
    assert _episode_rows.row_terms(sr) == (
        "CAST(CASE WHEN (success) THEN 1 ELSE 0 END AS BIGINT)",
        "CAST(1 AS BIGINT)",
        frozenset({"success"}),
    )
    builtin = va.MetricSet.builtin()
    projected = [
        m.name for m in builtin.resolve(list(builtin.metrics)) if _episode_rows.row_terms(m)
    ]
    assert projected == ["SR", "SSR", "SPL", "State-F1", *BUILTIN[3:]]  # the others: steps, goals
    for numerator in (
        "count(success)",  # null or not: another rule
        "count(DISTINCT success)",
        "sum(DISTINCT n_goals)",
        "fsum(spl ORDER BY n_goals)",
        "avg(spl)",
        "sum(spl, n_goals)",
        "main.sum(spl)",
        "sum(spl) + 0",
        "coalesce(sum(spl), 1)",
        "sum(sum(spl))",
        "sum(spl) FILTER (WHERE max(spl) > 0)",
        "sum(spl) FILTER (WHERE spl IN (SELECT 1))",
        "sum((SELECT 1))",
        "sum(spl) OVER ()",
        "sum(?)",
        "count(*) + 0",
        "count(*) FILTER (WHERE success IN (SELECT true))",
        "count(*) FILTER (WHERE COLUMNS('succ.*'))",
        "count(*) FILTER (WHERE success = ?)",
        "count(*) FILTER (WHERE sum(n_goals) OVER () > 1)",
        "count(*) ORDER BY success",
        "main.count_star()",
        "count(*) FILTER (WHERE success",  # does not parse
    ):
        assert _episode_rows.row_terms(Count("X", numerator, "count(*)")) is None, numerator
    assert _episode_rows.row_terms(Count("X", "count(*)", "count(*)", grain="steps")) is None


def _both(store, ratio, runs=None) -> tuple[pl.DataFrame | None, pl.DataFrame]:
    held = _episode_terms._held(store)
    projected = _episode_rows.projected_terms(store, ratio, held, (), runs)
    return projected, _episode_terms._grouped(store, ratio, held, (), runs)


def _bits(column: pl.Series) -> tuple[list[bool], list[int]]:
    """A float column's nulls and the bits of its values (-0.0 is not 0.0, NaN is NaN)."""
    values = column.fill_null(0.0).cast(pl.Float64).to_numpy().view(np.uint64)
    return column.is_null().to_list(), values.tolist()


def _same(projected: pl.DataFrame | None, grouped: pl.DataFrame) -> None:
    assert projected is not None
    assert projected.schema == grouped.schema
    assert projected.equals(grouped)  # the same rows and order
    for name, kind in grouped.schema.items():
        if kind.is_float():  # and the same bits
            assert _bits(projected[name]) == _bits(grouped[name]), name


def test_the_projection_is_the_grouped_query_on_the_sample(sample_out: Path):
    store = va.open_store(sample_out)
    runs = [r["run_id"] for r in store.manifest["runs"]]
    ratios = [va.MetricSet.builtin().get(n) for n in BUILTIN] + [*COUNTS, *SUMS]
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


FLOATS = st.none() | st.sampled_from([-0.0, 0.0, math.nan, -math.nan, math.inf, -math.inf])
FLOATS |= st.floats(allow_nan=True, allow_infinity=True, allow_subnormal=True)
"""Doubles as a sum's value may be: null, signed zeros, NaN (either sign), infinities."""

BIG = st.integers(-(2**63), 2**63 - 1) | st.sampled_from([-(2**63), 2**63 - 1, 0])
"""Integers of the whole BIGINT range: their sum is a HUGEINT."""


@st.composite
def _episodes(draw, base: pl.DataFrame) -> pl.DataFrame:
    """`base`'s rows in another order, their conditions' and sums' columns drawn (nulls,
    -0.0, NaN, infinities and large integers included)."""
    n = base.height
    order = draw(st.permutations(range(n)))
    maybe = st.none() | st.booleans()

    def floats(name: str, values=FLOATS) -> pl.Series:
        return pl.Series(name, draw(st.lists(values, min_size=n, max_size=n)), pl.Float64)

    steps = st.none() | st.integers(0, 255)  # (cast to a UTINYINT and a FLOAT in `SUMS`)
    return base[list(order)].with_columns(
        floats("vsps"),
        floats("cost_usd"),
        floats("latency_s", st.none() | st.floats(width=32)),
        pl.Series("n_switches", draw(st.lists(BIG, min_size=n, max_size=n)), pl.Int64),
        pl.Series("prefix_steps", draw(st.lists(steps, min_size=n, max_size=n)), pl.Int64),
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
    max_examples=10, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(data=st.data())
def test_the_projection_is_the_grouped_query_on_drawn_tables(drawn_out: Path, data):
    for run in ("A", "B"):
        (part,) = sorted((drawn_out / "episodes" / f"run_id={run}").glob("*.parquet"))
        base = pl.read_parquet(part)
        data.draw(_episodes(base)).write_parquet(part)
    va.clear_cache()
    store = va.open_store(drawn_out)
    for ratio in [*COUNTS, *SUMS]:
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
    assert _episode_rows.row_terms(WIDE) is not None
    projected, grouped = _both(store, WIDE)
    assert projected is None and grouped.height == 21


def test_a_condition_that_does_not_bind_is_grouped(pair_out: Path):
    store = va.open_store(pair_out)
    ratio = Count("X", "count(*) FILTER (WHERE no_such_column)", "count(*)")
    assert _episode_rows.row_terms(ratio) is not None  # a count, as far as its text says
    held = _episode_terms._held(store)
    assert _episode_rows.projected_terms(store, ratio, held, ()) is None
    with pytest.raises(va.QueryError):
        _episode_terms._grouped(store, ratio, held, ())


def test_a_sums_value_that_fails_on_a_row_filtered_out_fails_as_grouped(pair_out: Path):
    """The grouped query evaluates a sum's value on every row, the filter's false ones too
    (a cast out of range fails there): so does the projection, which then gives way."""
    store = va.open_store(pair_out)
    ratio = Count(
        "X", "sum(CAST(100 * n_goals AS UTINYINT)) FILTER (WHERE n_goals < 3)", "count(*)"
    )
    assert _episode_rows.row_terms(ratio) is not None
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


ONE_ROW = (
    ("DOUBLE", ["-0.0", "0.0", "nan", "-nan", "inf", "-inf", "1e308", "-5e-324", None]),
    ("FLOAT", ["-0.0", "nan", "-inf", "3.4e38", None]),
    ("BIGINT", ["9223372036854775807", "-9223372036854775808", "0", None]),
    ("HUGEINT", ["170141183460469231731687303715884105727", "-1", None]),
    ("UTINYINT", ["255", None]),
    ("DECIMAL(18, 3)", ["-0.000", "999999999999999.999", None]),
    ("DECIMAL(38, 10)", ["-9999999999999999999999999999.9999999999", None]),
    ("BOOLEAN", ["true", "false", None]),
)
"""Values of one row a sum reads, by type: signed zeros, NaN, infinities, the ends of the
integers' and decimals' ranges, null."""


def test_over_one_row_a_term_is_its_projection_to_the_type_and_the_bits():
    """Over one row, DuckDB's `count(*) FILTER (WHERE c)` is the projection's 1 or 0 (c true,
    false or null), a BIGINT as it; each sum of `_SUMS`, filtered or not, is its
    `list_aggregate` over the row's value: the same type and text (-0.0 summed is 0.0,
    -nan stays -nan, a sum of integers a HUGEINT, of a DECIMAL(18, 3) a DECIMAL(38, 3)),
    the grouped query's value as `ratio_terms` wraps it (null: 0)."""
    import duckdb

    from vge_analytics.store._ratios import ratio_terms

    row = "(SELECT 1 AS k, CAST(? AS {kind}) AS x, CAST(? AS BOOLEAN) AS c) AS g"
    seen = set()
    with duckdb.connect() as con:
        for name in sorted(_episode_rows._SUMS) + ["count"]:
            for kind, values in ONE_ROW:
                if name != "sum" and kind == "BOOLEAN":
                    continue  # no such fsum
                for value in values:
                    for condition in ("", " FILTER (WHERE c)"):
                        call = "count(*)" if name == "count" else f"{name}(x)"
                        ratio = Count("X", call + condition, "count(*)")
                        numerator, _, names = _episode_rows.row_terms(ratio)
                        assert names == ({"c"} if condition else set()) | (
                            set() if name == "count" else {"x"}
                        )
                        ((term, _),) = ratio_terms([ratio])[:1]
                        for c in (True, False, None):
                            sql = "SELECT {0}, typeof({0}), CAST({0} AS VARCHAR) FROM " + row
                            grouped = con.execute(
                                sql.format(term, kind=kind) + " GROUP BY k", [value, c]
                            ).fetchall()
                            projected = con.execute(
                                sql.format(numerator, kind=kind), [value, c]
                            ).fetchall()
                            assert projected[0][1:] == grouped[0][1:], (call, kind, value, c)
                            seen.add((projected[0][1], projected[0][2]))
    assert {("DOUBLE", "0.0"), ("DOUBLE", "-nan"), ("DOUBLE", "-inf")} <= seen
    assert ("HUGEINT", "-9223372036854775808") in seen and ("DECIMAL(38,3)", "0.000") in seen
    assert ("BIGINT", "1") in seen and ("BIGINT", "0") in seen


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
