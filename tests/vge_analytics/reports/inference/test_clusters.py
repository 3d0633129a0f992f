"""The cluster bootstrap and the clustered (CR1) SE of a paired difference of pooled metrics,
checked against statsmodels' cluster-robust OLS and WLS (and by hand in test_compare.py)."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest
import statsmodels.api as sm
from hypothesis import given, settings
from hypothesis import strategies as st

from vge_analytics.reports.inference import (
    bootstrap_totals,
    cluster_code_column,
    cluster_codes,
    cluster_sums,
    cr1_variance,
    linearized,
    paired_difference,
)
from vge_analytics.reports.inference._clusters import float_matrix


def test_cluster_codes_follow_sorted_labels() -> None:
    codes, names = cluster_codes(["b", "a", "c", "a"])
    assert names == ["a", "b", "c"] and codes.tolist() == [1, 0, 2, 0]
    codes, names = cluster_codes([])
    assert names == [] and codes.tolist() == []


def test_cluster_sums() -> None:
    values = np.array([[1.0, 2.0], [3.0, 4.0], [5.0, 6.0]])
    assert cluster_sums(values, np.array([1, 0, 1]), 2).tolist() == [[3.0, 4.0], [6.0, 8.0]]


def test_bootstrap_draws_are_seeded_and_shared_by_cluster_count() -> None:
    rng = np.random.default_rng(5)
    a, b, c = rng.random((7, 4)), rng.random((7, 4)), rng.random((9, 4))
    first = bootstrap_totals([a, b, c], seed=3, resamples=600)
    again = bootstrap_totals([a, c], seed=3, resamples=600)
    assert np.array_equal(first[0], again[0]) and np.array_equal(first[2], again[1])
    # a and b (7 clusters each) got the same draws: their totals differ by the draws of a - b
    counts = np.random.default_rng(3).multinomial(7, np.full(7, 1 / 7), size=250)
    assert np.allclose(first[0][:250] - first[1][:250], counts @ (a - b))
    other = bootstrap_totals([a], seed=4, resamples=600)[0]
    assert not np.array_equal(other, first[0])


def _ratio_pair(rng: np.random.Generator, n: int, g: int) -> tuple[np.ndarray, np.ndarray]:
    """(n x 4) episode terms of one metric (A num, A den, B num, B den) and the clusters."""
    den_a = rng.integers(0, 4, n).astype(float)
    den_b = rng.integers(0, 4, n).astype(float)
    num_a = rng.binomial(den_a.astype(int), 0.4).astype(float)
    num_b = rng.binomial(den_b.astype(int), 0.6).astype(float)
    return np.column_stack([num_a, den_a, num_b, den_b]), rng.integers(0, g, n)


def test_paired_ratio_se_equals_stacked_cluster_robust_wls() -> None:
    """For a ratio metric (sum num / sum den per run), B - A and its clustered SE equal the
    difference of the two coefficients of a WLS of num/den on run indicators, weights den,
    cluster-robust by cluster; statsmodels' CR1 factor is G/(G-1) * (N-1)/(N-K), ours (one
    parameter, the paired difference) G/(G-1)."""
    rng = np.random.default_rng(11)
    for n, g in ((80, 12), (300, 40)):
        terms, groups = _ratio_pair(rng, n, g)
        scale = 100.0
        sums = cluster_sums(terms, groups, g)
        diff = paired_difference(terms.sum(axis=0), [scale])[0]
        se = np.sqrt(cr1_variance(linearized(sums, [scale])))[0]
        rows = []
        for num, den, is_b in ((0, 1, 0.0), (2, 3, 1.0)):
            keep = terms[:, den] > 0
            for y, w, c in zip(
                terms[keep, num] / terms[keep, den], terms[keep, den], groups[keep], strict=True
            ):
                rows.append((y, w, c, is_b))
        y, w, c, is_b = (np.array(col) for col in zip(*rows, strict=True))
        x = np.column_stack([1.0 - is_b, is_b])
        fit = sm.WLS(scale * y, x, weights=w).fit(cov_type="cluster", cov_kwds={"groups": c})
        contrast = np.array([-1.0, 1.0])
        n_rows, k = len(y), 2
        var = contrast @ fit.cov_params() @ contrast / ((n_rows - 1) / (n_rows - k))
        assert abs(diff - contrast @ fit.params) < 1e-9
        assert abs(se - np.sqrt(var)) < 1e-9


def test_sr_difference_se_equals_cluster_robust_ols() -> None:
    rng = np.random.default_rng(2)
    n, g = 200, 17
    a, b = rng.integers(0, 2, n).astype(float), rng.integers(0, 2, n).astype(float)
    groups = rng.integers(0, g, n)
    terms = np.column_stack([a, np.ones(n), b, np.ones(n)])
    se = np.sqrt(cr1_variance(linearized(cluster_sums(terms, groups, g), [100.0])))[0]
    naive = np.sqrt(cr1_variance(linearized(terms, [100.0])))[0]
    d = 100.0 * (b - a)
    fit = sm.OLS(d, np.ones((n, 1))).fit(cov_type="cluster", cov_kwds={"groups": groups})
    assert abs(se - fit.bse[0]) < 1e-9
    assert abs(naive - sm.OLS(d, np.ones((n, 1))).fit(cov_type="HC1").bse[0]) < 1e-9


def test_one_cluster_has_no_variance_and_an_empty_metric_no_difference() -> None:
    assert np.isnan(cr1_variance(np.array([[1.0]])))[0]
    totals = np.array([1.0, 0.0, 2.0, 4.0])
    assert np.isnan(paired_difference(totals, [100.0]))[0]
    assert paired_difference(np.array([1.0, 2.0, 3.0, 4.0]), [100.0])[0] == pytest.approx(25.0)


def test_cluster_code_column_gives_the_codes_of_cluster_codes_per_group():
    """The expression over a whole frame numbers each group's labels as `cluster_codes` does
    on that group's list (sorted labels; non-ASCII ones and a null, read as `None`, too)."""
    rng = np.random.default_rng(3)
    labels = ["dev_b", "dev_a", "Dev_c", "é-device", "dev_ä", "日本", "None", None, "dev_a10"]
    frame = pl.DataFrame(
        {
            "group": rng.integers(0, 4, 400).tolist(),
            "device_id": [labels[i] for i in rng.integers(0, len(labels), 400)],
        }
    )
    coded = frame.with_columns(cluster_code_column("device_id", ["group"]))
    for _, part in coded.partition_by("group", as_dict=True, maintain_order=True).items():
        codes, names = cluster_codes(part["device_id"].to_list())
        assert part["device_id:cluster"].to_list() == codes.tolist()
        assert part["device_id:cluster"].max() + 1 == len(names)
    whole = frame.with_columns(cluster_code_column("device_id", []))
    assert (
        whole["device_id:cluster"].to_list()
        == cluster_codes(frame["device_id"].to_list())[0].tolist()
    )


def _by_python(frame: pl.DataFrame, columns) -> np.ndarray:
    """What the intervals did before `float_matrix`: numpy's conversion of polars' values
    (a decimal column as Python `Decimal`s, each made a float by `float(Decimal)`)."""
    return np.ascontiguousarray(frame.select(columns).to_numpy(), dtype=np.float64)


def _same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    return (
        a.shape == b.shape
        and a.flags.c_contiguous
        and np.array_equal(a.view(np.int64), b.view(np.int64))
    )


EDGES = [0, 1, -1, 2**53, 2**53 + 1, 2**53 + 3, -(2**53 + 1), 2**63 - 1, -(2**63), 2**64 + 1]
EDGES += [10**36 - 1, -(10**36 - 1), 2**100 + 2**47, 2**100 + 2**47 + 1, 3 * 2**70 - 1]
"""Integers whose doubles need care (ties, just past a tie, past 64 bits), within what a
DECIMAL(38, s) of polars holds for every scale used here."""


@pytest.mark.parametrize("scale", [0, 2, 9, 30])
def test_float_matrix_rounds_decimals_as_python_does(scale: int) -> None:
    # 2**53 + 1 lies halfway between two doubles (ties to even: 2**53); 2**100 + 2**47 + 1
    # just above a halfway point (rounds up): a conversion through another type would miss
    import decimal

    values = [decimal.Decimal(v).scaleb(-scale) for v in EDGES]
    frame = pl.DataFrame(
        {
            "d": pl.Series(values, dtype=pl.Decimal(38, scale)),
            "i": pl.Series(range(len(values)), dtype=pl.Int64),
            "f": pl.Series([-0.0, *([1.5] * (len(values) - 1))], dtype=pl.Float64),
        }
    )
    got = float_matrix(frame, ["d", "i", "f"])
    assert _same_bits(got, _by_python(frame, ["d", "i", "f"]))
    assert got[:, 0].tolist() == [float(v) for v in values]
    assert got[2, 0] == -float(decimal.Decimal(1).scaleb(-scale))
    assert np.signbit(got[0, 2])  # -0.0 kept


@settings(max_examples=50, deadline=None)
@given(
    st.lists(st.integers(-(10**36) + 1, 10**36 - 1), min_size=1, max_size=40),
    st.integers(0, 12),
)
def test_float_matrix_matches_python_on_drawn_decimals(ints: list[int], scale: int) -> None:
    import decimal

    values = [decimal.Decimal(v).scaleb(-scale) for v in ints]
    frame = pl.DataFrame({"d": pl.Series(values, dtype=pl.Decimal(38, scale))})
    assert _same_bits(float_matrix(frame, ["d"]), _by_python(frame, ["d"]))
