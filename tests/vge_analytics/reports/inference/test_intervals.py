"""A metric's interval per group (the Leaderboard's): by hand on the 3 x 2 case, and its
clustered SE against statsmodels on the bundled sample."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import polars as pl
import pytest
import statsmodels.api as sm

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
