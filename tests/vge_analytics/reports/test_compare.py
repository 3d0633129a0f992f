"""`compare` on a constructed pair with a known answer.

Pair (conftest): ten copies ep00..ep09 of the kettle_c task. A solves ep00 and ep01 (full
kettle_c log), B solves ep01..ep06; every other episode plays the first two kettle_c steps
(a parse failure, then goal 1) and the log ends. B also played ep10, which A did not.

- Common episodes: ep00..ep09 (10); ep10 is B's only.
- SR: A 2/10 = 20%, B 6/10 = 60%, B - A = 40 points.
- McNemar: b (A only) = 1 (ep00), c (B only) = 5 (ep02..ep06), n = 6;
  p = 2 * P(X <= 1 | Bin(6, 1/2)) = 2 * (1 + 6) / 64 = 14/64 = 0.21875.
- Errors: the full log has action_error x3 + invalid_coord x1, the short one action_error x1.
  A: 2 full + 8 short -> action_error 14, invalid_coord 2 (87.5%, 12.5%);
  B (common only): 6 full + 4 short -> action_error 22, invalid_coord 6 (78.57%, 21.43%);
  difference B - A: action_error -8.93 pp, invalid_coord +8.93 pp (= 600/28 - 12.5).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import polars as pl
import pytest
import statsmodels.api as sm

import vge_analytics as va


def test_mcnemar_exact_values() -> None:
    assert va.mcnemar_exact(0, 0) == 1.0
    assert va.mcnemar_exact(1, 5) == 14 / 64
    assert va.mcnemar_exact(5, 1) == 14 / 64
    assert va.mcnemar_exact(0, 10) == 2 / 1024
    assert va.mcnemar_exact(3, 3) == 1.0  # capped at 1
    # 2 * P(X <= 2 | Bin(12, 1/2)) = 2 * (1 + 12 + 66) / 4096
    assert va.mcnemar_exact(2, 10) == 158 / 4096


def test_compare_known_answer(pair_out: Path) -> None:
    c = va.compare(pair_out, "A", "B", seed=7, resamples=500, cluster="episode")
    assert (c.n_common, c.n_only_a, c.n_only_b) == (10, 0, 1)
    assert (c.model_a, c.model_b) == ("gemini-sim", "human-sim")
    sr = c.metrics.filter(pl.col("metric") == "SR").row(0, named=True)
    assert sr["A"] == pytest.approx(20.0) and sr["B"] == pytest.approx(60.0)
    assert sr["diff"] == pytest.approx(40.0)
    assert sr["ci_low"] <= sr["diff"] <= sr["ci_high"]
    assert sr["ci_low"] >= -100 and sr["ci_high"] <= 100
    m = c.mcnemar.row(0, named=True)
    assert (m["both"], m["a_only"], m["b_only"], m["neither"]) == (1, 1, 5, 3)
    assert m["p_value"] == 0.21875
    flips = c.flips
    assert flips.filter(pl.col("direction") == "A_only")["episode_id"].to_list() == ["ep00"]
    assert flips.filter(pl.col("direction") == "B_only")["episode_id"].to_list() == [
        "ep02",
        "ep03",
        "ep04",
        "ep05",
        "ep06",
    ]
    errors = {r["error_type"]: r for r in c.errors.iter_rows(named=True)}
    assert (errors["action_error"]["count_a"], errors["action_error"]["count_b"]) == (14, 22)
    assert (errors["invalid_coord"]["count_a"], errors["invalid_coord"]["count_b"]) == (2, 6)
    assert errors["invalid_coord"]["diff_pp"] == pytest.approx(600 / 28 - 12.5)
    assert errors["action_error"]["diff_pp"] == pytest.approx(2200 / 28 - 87.5)
    assert math.isclose(c.errors["diff_pp"].sum(), 0.0, abs_tol=1e-9)


def test_one_cluster_is_a_stated_null(pair_out: Path) -> None:
    """The pair's ten episodes are copies of one device: no device-clustered interval, SE or
    p-value, and the summary says why; the values and McNemar's test stay."""
    c = va.compare(pair_out, "A", "B", resamples=50)
    assert c.n_clusters == 1 and c.cluster == "device"
    assert "all in one device" in c.summary["note"][0]
    sr = c.metrics.filter(pl.col("metric") == "SR").row(0, named=True)
    assert sr["diff"] == pytest.approx(40.0)
    assert all(sr[k] is None for k in ("ci_low", "ci_high", "se", "deff", "p_value", "p_adjusted"))
    assert c.mcnemar["p_value"][0] == 0.21875


def test_compare_is_seeded(pair_out: Path) -> None:
    """The same seed gives the same intervals and p-values; another seed other intervals
    (and the same point estimates)."""
    a = va.compare(pair_out, "A", "B", seed=3, resamples=300, cluster="episode").metrics
    b = va.compare(pair_out, "A", "B", seed=3, resamples=300, cluster="episode").metrics
    assert a.equals(b)
    other = va.compare(pair_out, "A", "B", seed=4, resamples=300, cluster="episode").metrics
    assert other["diff"].equals(a["diff"])  # point estimates do not depend on the seed
    assert other["se"].equals(a["se"])  # nor does the analytic standard error
    # every interval with a width moves (VSPS, GVPE and EER are equal in every resample)
    pairs = zip(a["ci_low"], a["ci_high"], other["ci_low"], other["ci_high"], strict=True)
    moved = [(x, y) != (u, v) for x, y, u, v in pairs if y - x > 0]
    assert len(moved) == 9 and all(moved), "the seed does not move the intervals"
    assert not a["p_value"].equals(other["p_value"])  # 2^10 patterns > 300: random ones


def test_compare_swapped_is_negated(pair_out: Path) -> None:
    ab = va.compare(pair_out, "A", "B", resamples=50).metrics
    ba = va.compare(pair_out, "B", "A", resamples=50).metrics
    for x, y in zip(ab["diff"].to_list(), ba["diff"].to_list(), strict=True):
        assert x == pytest.approx(-y)


def test_compare_errors(pair_out: Path, hand_out: Path) -> None:
    with pytest.raises(va.UnknownRunError, match="unknown run 'C'"):
        va.compare(pair_out, "A", "C")
    with pytest.raises(va.AnalyticsError, match="no episode in common"):
        va.compare(hand_out, "kettle-vlm", "oven-human")
    with pytest.raises(va.AnalyticsError, match="two different runs"):
        va.compare(pair_out, "A", "A")


# ------------------------------------------------------------- clustered, worked by hand


def test_clustered_compare_worked_by_hand(clustered_out: Path) -> None:
    """Three devices of two episodes (conftest's CLUSTERED_SUCCESS), A against B.

    Success (A, B): kettle_1 e1 (1, 1), e2 (0, 1); kettle_2 e3 (1, 0), e4 (1, 1);
    kettle_3 e5 (0, 1), e6 (0, 1). SR: A 3/6 = 50, B 5/6 = 83.33, B - A = 33.33 points.
    Per-episode differences d (points): 0, 100, -100, 0, 100, 100; mean 200/6.
    - Clustered (CR1): the residuals d - mean summed per device are 100/3, -500/3, 400/3,
      so var = G/(G-1) * sum u_g^2 / n^2 = 3/2 * (10000/9) * 42 / 36 = 1944.44, SE 44.0959.
    - Naive: the residuals are (100/3) * (-1, 2, -4, -1, 2, 2), sum of squares
      (10000/9) * 30, var = n/(n-1) * that / n^2 = 6/5 * 33333.3 / 36 = 1111.11, SE 33.333.
    - Design effect 1944.44 / 1111.11 = 1.75.
    - Sign flip, exact (2^3 = 8 patterns): the devices' sums of d are 100, -100, 200; the
      sums of +-100 +-100 +-200 reach |200| in 6 patterns of 8: p = 0.75. SSR = 1/3 + 2/3 *
      success here (kettle_c has three goals; the short log completes the first), so its
      difference is 2/3 of SR's and its p-value the same; Holm over the two: min(1, 2 *
      0.75) = 1; Benjamini-Hochberg: 0.75.
    - The bootstrap draws 3 devices of means 50, -50, 100; all three the same device happens
      with chance 1/27 > 2.5%, so the percentile interval is [-50, 100].
    - McNemar: A only e3, B only e2, e5, e6: p = 2 * (1 + 4) / 16 = 0.625. Clustered
      (Durkalski): D_g = a_only - b_only = -1, 1, -2; X2 = 2^2 / 6; p = P(chi2_1 > 2/3)
      = 0.414216.
    """
    c = va.compare(clustered_out, "A", "B", metrics="SR,SSR", resamples=2000)
    assert (c.n_common, c.n_clusters, c.cluster) == (6, 3, "device")
    assert c.summary["test"][0] == "cluster sign-flip, exact (all 8 patterns)"
    sr, ssr = c.metrics.iter_rows(named=True)
    assert (sr["A"], sr["B"], sr["diff"]) == pytest.approx((50.0, 500 / 6, 200 / 6))
    assert sr["se"] == pytest.approx(math.sqrt(1260000 / 648), rel=1e-12)
    assert sr["se_naive"] == pytest.approx(100 / 3, rel=1e-12)
    assert sr["deff"] == pytest.approx(1.75, rel=1e-12)
    assert (sr["ci_low"], sr["ci_high"]) == (-50.0, 100.0)
    assert sr["p_value"] == 0.75 and ssr["p_value"] == 0.75
    assert ssr["diff"] == pytest.approx(2 / 3 * sr["diff"])
    assert ssr["deff"] == pytest.approx(1.75, rel=1e-12)
    assert sr["p_adjusted"] == ssr["p_adjusted"] == 1.0
    bh = va.compare(clustered_out, "A", "B", metrics="SR,SSR", correction="bh").metrics
    assert bh["p_adjusted"].to_list() == [0.75, 0.75]
    none = va.compare(clustered_out, "A", "B", metrics="SR", correction="none").metrics
    assert none["p_adjusted"].to_list() == [0.75]
    m = c.mcnemar.row(0, named=True)
    assert (m["a_only"], m["b_only"], m["p_value"]) == (1, 3, 0.625)
    assert m["p_cluster"] == pytest.approx(math.erfc(math.sqrt(1 / 3)), rel=1e-12)
    assert m["p_cluster"] == pytest.approx(0.414216, abs=1e-6)


def test_episode_clusters_are_the_naive_statistics(clustered_out: Path) -> None:
    c = va.compare(clustered_out, "A", "B", metrics="SR", cluster="episode")
    sr = c.metrics.row(0, named=True)
    assert c.n_clusters == 6
    assert sr["se"] == pytest.approx(100 / 3, rel=1e-12) and sr["deff"] == pytest.approx(1.0)
    # one device per category here: the whole benchmark is one cluster
    one = va.compare(clustered_out, "A", "B", metrics="SR", cluster="category")
    assert one.n_clusters == 1 and one.metrics["se"][0] is None


def _paired_sr(out: Path, run_a: str, run_b: str) -> pl.DataFrame:
    eps = va.episodes(out, where={"run_id": [run_a, run_b]})
    a = eps.filter(pl.col("run_id") == run_a).select("episode_id", "device_id", "success")
    b = eps.filter(pl.col("run_id") == run_b).select("episode_id", pl.col("success").alias("b"))
    return a.join(b, on="episode_id").sort("episode_id")


def test_clustered_se_equals_statsmodels_on_the_sample(sample_out: Path) -> None:
    """The clustered SE of the paired SR difference is statsmodels' OLS of the per-episode
    differences on a constant with cluster-robust covariance (groups = device), to 1e-9."""
    for run_a, run_b in (("sim-human", "sim-vlm-f"), ("sim-vlm-a", "sim-vlm-e")):
        c = va.compare(sample_out, run_a, run_b, metrics="SR", resamples=20)
        paired = _paired_sr(sample_out, run_a, run_b)
        d = 100.0 * (paired["b"].cast(float) - paired["success"].cast(float)).to_numpy()
        groups = paired["device_id"].rank("dense").to_numpy()
        ones = np.ones((len(d), 1))
        fit = sm.OLS(d, ones).fit(cov_type="cluster", cov_kwds={"groups": groups})
        naive = sm.OLS(d, ones).fit(cov_type="HC1")
        sr = c.metrics.row(0, named=True)
        assert abs(sr["se"] - fit.bse[0]) < 1e-9
        assert abs(sr["se_naive"] - naive.bse[0]) < 1e-9
        assert sr["diff"] == pytest.approx(d.mean(), abs=1e-9)
    assert c.n_common == 312 and c.n_clusters == 52
