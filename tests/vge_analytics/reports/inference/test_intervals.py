"""A metric's interval per group (the Leaderboard's): by hand on the 3 x 2 case, and its
clustered SE against statsmodels on the bundled sample."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import polars as pl
import pytest
import statsmodels.api as sm
from hypothesis import given, settings
from hypothesis import strategies as st

import vge_analytics as va


def test_one_runs_interval_by_hand(clustered_out: Path) -> None:
    """Run A solves e1, e3, e4 of (e1, e2) (e3, e4) (e5, e6): SR 50; device means 50, 100, 0.
    Residuals of success (points) summed per device: 0, +100, -100; CR1 var = 3/2 * 20000 / 36
    = 833.3, SE 28.87; naive: residuals +-50 on all six, var = 6/5 * 15000 / 36 = 500, SE 22.36;
    design effect 5/3. The bootstrap draws three devices of means 50, 100, 0 (each alike with
    chance 1/27 > 2.5%): interval [0, 100]."""
    rows = va.metric_intervals(clustered_out, by=["run_id"]).filter(pl.col("run_id") == "A")
    row = rows.row(0, named=True)
    assert row["value"] == 50.0 and (row["n_episodes"], row["n_clusters"]) == (6, 3)
    assert row["se"] == pytest.approx(math.sqrt(1.5 * 20000 / 36), rel=1e-12)
    assert row["se_naive"] == pytest.approx(math.sqrt(500.0), rel=1e-12)
    assert row["deff"] == pytest.approx(5 / 3, rel=1e-12)
    assert (row["ci_low"], row["ci_high"]) == (0.0, 100.0)
    # one category: one cluster, a stated null
    by_category = va.metric_intervals(clustered_out, by=["run_id"], cluster="category")
    assert by_category["se"].null_count() == by_category.height
    assert by_category["n_clusters"].to_list() == [1] * 4


def test_grouped_by_a_run_column_and_filtered(clustered_out: Path) -> None:
    """model-b pools B and its seeds: 11 successes of 18 (run, episode) rows."""
    rows = va.metric_intervals(clustered_out, by=["model"], where={"model": "model-b"})
    assert rows["model"].to_list() == ["model-b"]
    assert rows["value"][0] == pytest.approx(1100 / 18) and rows["n_episodes"][0] == 18
    with pytest.raises(va.UnknownColumnError):
        va.metric_intervals(clustered_out, by=["nope"])


def test_a_runs_se_equals_statsmodels_on_the_sample(sample_out: Path) -> None:
    intervals = va.metric_intervals(sample_out, by=["run_id"], resamples=20)
    eps = va.episodes(sample_out, columns=["run_id", "episode_id", "device_id", "success"])
    for row in intervals.iter_rows(named=True):
        mine = eps.filter(pl.col("run_id") == row["run_id"])
        y = 100.0 * mine["success"].cast(float).to_numpy()
        groups = mine["device_id"].rank("dense").to_numpy()
        fit = sm.OLS(y, np.ones((len(y), 1))).fit(cov_type="cluster", cov_kwds={"groups": groups})
        assert abs(row["se"] - fit.bse[0]) < 1e-9
        assert row["value"] == pytest.approx(y.mean(), abs=1e-9)


def test_sorted_by_keeps_a_frame_in_order_and_sorts_one_that_is_not():
    from vge_analytics.reports.inference._intervals import sorted_by

    keys = ["model", "run_id", "episode_id"]
    ordered = pl.DataFrame(
        {
            "model": ["a", "a", "b", "b", None, None],  # nulls last
            "run_id": ["r2", "r2", "r1", "r3", "r0", "r0"],
            "episode_id": ["e1", "e2", "e9", "e0", "e1", "e2"],
            "x": [1, 2, 3, 4, 5, 6],
        }
    )
    assert sorted_by(ordered, keys) is ordered  # in order: not sorted again
    for moved in ([1, 0, 2, 3, 4, 5], [0, 1, 3, 2, 4, 5], [4, 0, 1, 2, 3, 5], [0, 1, 2, 3, 5, 4]):
        shuffled = ordered[moved]
        got = sorted_by(shuffled, keys)
        assert got is not shuffled and got.equals(ordered)
    floats = ordered.with_columns(pl.col("x").cast(pl.Float64))
    assert sorted_by(floats, ["x", "episode_id"]) is not floats  # not a type checked here


@settings(max_examples=60, deadline=None)
@given(
    st.lists(
        st.tuples(st.sampled_from(["a", "b", "é", None]), st.integers(-3, 3) | st.none()),
        min_size=2,
        max_size=30,
    )
)
def test_sorted_by_gives_the_sort_whatever_the_rows(rows):
    from vge_analytics.reports.inference._intervals import sorted_by

    frame = pl.DataFrame(
        {
            "g": pl.Series([r[0] for r in rows], dtype=pl.String),
            "n": pl.Series([r[1] for r in rows], dtype=pl.Int64),
            "episode_id": [f"e{i:03d}" for i in range(len(rows))],  # unique, as an episode
        }
    )
    keys = ["g", "n", "episode_id"]
    expected = frame.sort(keys, nulls_last=True)
    assert sorted_by(frame, keys).equals(expected)
    assert sorted_by(expected, keys) is expected
