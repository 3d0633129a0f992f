"""The power formulas by hand, and the ANOVA intra-cluster correlation."""

from __future__ import annotations

import pytest
from scipy import stats

from vge_analytics.reports.inference import (
    anova_icc,
    clusters_needed,
    design_effect,
    effective_size,
    minimal_detectable,
    z_sum,
)


def test_z_and_the_minimal_detectable_difference() -> None:
    assert z_sum(0.05, 0.8) == pytest.approx(stats.norm.ppf(0.975) + stats.norm.ppf(0.8))
    assert z_sum(0.05, 0.8) == pytest.approx(2.801585, abs=1e-6)
    assert minimal_detectable(2.0, 0.05, 0.8) == pytest.approx(2 * 2.801585, abs=1e-5)
    # SE 2 with 50 clusters; detecting 2.8016 (the MDE / 2) needs 4 times the clusters
    assert clusters_needed(2.0, 50, z_sum(0.05, 0.8), 0.05, 0.8) == 200
    assert clusters_needed(0.01, 50, 10.0, 0.05, 0.8) == 2  # never fewer than two


def test_design_effect_of_unequal_clusters() -> None:
    assert effective_size([2, 2, 2]) == 2.0
    assert effective_size([1, 3]) == pytest.approx(10 / 4)
    assert design_effect([1, 3], 0.2) == pytest.approx(1 + 1.5 * 0.2)


def test_anova_icc_by_hand() -> None:
    """Clusters (1, 1, 0), (0, 0, 0), (1, 1, 1): means 2/3, 0, 1, grand 5/9. MSB =
    3 * ((1/9)^2 + (5/9)^2 + (4/9)^2) / 2 = 3 * 42/81 / 2 = 7/9; within, only the first
    cluster varies: 2 * (1/3)^2 + (2/3)^2 = 2/3, MSW = (2/3) / 6 = 1/9; m0 = 3.
    ICC = (7/9 - 1/9) / (7/9 + 2 * 1/9) = (6/9) / (9/9) = 2/3."""
    assert anova_icc([[1, 1, 0], [0, 0, 0], [1, 1, 1]]) == pytest.approx(2 / 3)
    assert anova_icc([[1, 0], [1, 0]]) == 0.0  # clipped: within varies, between does not
    assert anova_icc([[1, 1]]) is None and anova_icc([[1], [0]]) is None
    assert anova_icc([[1, 1], [1, 1]]) is None  # no variation at all
