"""The cluster sign-flip test, the clustered McNemar test and the corrections, by hand and
against scipy and statsmodels."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats
from statsmodels.stats.contingency_tables import mcnemar
from statsmodels.stats.multitest import multipletests

from vge_analytics import AnalyticsError
from vge_analytics.reports.inference import adjust_p, clustered_mcnemar, sign_flip_p


def _sr_sums(per_cluster: list[tuple[int, int, int]]) -> np.ndarray:
    """(G x 4) sums of SR terms from (episodes, A successes, B successes) per cluster."""
    return np.array([[a, n, b, n] for n, a, b in per_cluster], dtype=float)


def test_exact_sign_flip_by_hand() -> None:
    """Devices' sums of d (points): 100, -100, 200 (test_compare's hand-worked case): of the
    8 patterns, the sums +-100 +-100 +-200 reach |200| in 6: p = 0.75."""
    sums = _sr_sums([(2, 1, 2), (2, 2, 1), (2, 0, 2)])
    p, exact = sign_flip_p(sums, [100.0], seed=0, resamples=2000)
    assert exact and p.tolist() == [0.75]
    # every device the same way: only the observed pattern and its mirror reach it, 2/8
    p, _ = sign_flip_p(_sr_sums([(2, 0, 1), (2, 0, 1), (2, 0, 2)]), [100.0], 0, 2000)
    assert p.tolist() == [0.25]
    # no difference at all: p = 1
    p, _ = sign_flip_p(_sr_sums([(2, 1, 1), (3, 2, 2)]), [100.0], 0, 2000)
    assert p.tolist() == [1.0]


def test_random_sign_flip_is_seeded_and_bounded() -> None:
    rng = np.random.default_rng(0)
    per = [(3, int(rng.integers(0, 4)), int(rng.integers(0, 4))) for _ in range(40)]
    sums = _sr_sums(per)
    p, exact = sign_flip_p(sums, [100.0], seed=1, resamples=999)
    assert not exact and 1 / 1000 <= p[0] <= 1
    assert sign_flip_p(sums, [100.0], 1, 999)[0].tolist() == p.tolist()
    # a large shift in every device: the observed pattern alone is as extreme
    strong = _sr_sums([(5, 0, 5)] * 40)
    assert sign_flip_p(strong, [100.0], 1, 999)[0].tolist() == [1 / 1000]


def test_clustered_mcnemar_against_scipy_and_mcnemar() -> None:
    a_only, b_only = np.array([0, 1, 0]), np.array([1, 0, 2])
    statistic = (-2) ** 2 / 6
    assert clustered_mcnemar(a_only, b_only) == pytest.approx(
        stats.chi2.sf(statistic, 1), rel=1e-12
    )
    assert clustered_mcnemar(np.zeros(3), np.zeros(3)) == 1.0
    # one episode per cluster: McNemar's uncorrected chi-square test
    a_only, b_only = np.array([1] * 7 + [0] * 19), np.array([0] * 7 + [1] * 12 + [0] * 7)
    table = [[30, int(a_only.sum())], [int(b_only.sum()), 40]]
    expected = mcnemar(table, exact=False, correction=False).pvalue
    assert clustered_mcnemar(a_only, b_only) == pytest.approx(expected, rel=1e-12)


def test_holm_and_bh_by_hand() -> None:
    """p = 0.01, 0.04, 0.03, 0.2. Holm: 4 x 0.01 = 0.04; 3 x 0.03 = 0.09; 2 x 0.04 = 0.08,
    raised to 0.09; 1 x 0.2 = 0.2. BH: 0.2; 4/3 x 0.04 = 0.0533; 4/2 x 0.03 = 0.06, lowered
    to 0.0533; 4 x 0.01 = 0.04."""
    p = [0.01, 0.04, 0.03, 0.2]
    assert adjust_p(p, "holm") == pytest.approx([0.04, 0.09, 0.09, 0.2])
    assert adjust_p(p, "bh") == pytest.approx([0.04, 0.16 / 3, 0.16 / 3, 0.2])
    assert adjust_p(p, "none") == p
    assert adjust_p([0.5, None, math.nan, 0.6], "holm") == [1.0, None, None, 1.0]
    with pytest.raises(AnalyticsError, match="unknown correction 'bonferroni'"):
        adjust_p(p, "bonferroni")


@pytest.mark.parametrize(("ours", "theirs"), [("holm", "holm"), ("bh", "fdr_bh")])
def test_corrections_equal_statsmodels(ours: str, theirs: str) -> None:
    rng = np.random.default_rng(4)
    for size in (1, 2, 7, 40):
        p = rng.random(size) ** 3
        p[: size // 3] = p[0]  # ties
        expected = multipletests(p, method=theirs)[1]
        assert adjust_p(list(p), ours) == pytest.approx(list(expected), abs=1e-12)
