"""Power of a paired comparison under clustering (normal approximation; docs/STATISTICS.md).

A two-sided test at level alpha detects a true difference delta with probability `power`
when `delta >= (z_{1-alpha/2} + z_{power}) * SE`: that multiple of the standard error is the
minimal detectable difference. The clustered SE of a mean over G clusters of m episodes
shrinks as 1 / sqrt(G), so G' = G * (MDE / delta)^2 clusters detect delta.

For planning without runs, the per-episode variance of the paired difference of success
between two runs with rates p and p + delta is at most `p(1-p) + q(1-q)` (q = p + delta;
equality when the runs' successes are independent, a positive correlation lowers it), and
clustering multiplies it by the design effect `1 + (m_eff - 1) * icc`, with m_eff =
sum(m_g^2) / sum(m_g) the size-weighted mean cluster size (the mean for equal clusters) and
icc the intra-cluster correlation.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from statistics import NormalDist

_NORMAL = NormalDist()


def z_sum(alpha: float, power: float) -> float:
    """`z_{1-alpha/2} + z_{power}`."""
    return _NORMAL.inv_cdf(1.0 - alpha / 2.0) + _NORMAL.inv_cdf(power)


def minimal_detectable(se: float, alpha: float, power: float) -> float:
    """The smallest true difference detected with the given power (two-sided, level alpha)."""
    return z_sum(alpha, power) * se


def clusters_needed(se: float, n_clusters: int, delta: float, alpha: float, power: float) -> int:
    """Clusters (like the observed ones) needed to detect `delta`: G * (MDE / delta)^2,
    rounded up (at least 2)."""
    mde = minimal_detectable(se, alpha, power)
    return max(2, math.ceil(n_clusters * (mde / delta) ** 2 - 1e-9))


def effective_size(sizes: Sequence[int]) -> float:
    """`sum(m^2) / sum(m)`: the cluster size a design effect uses for unequal clusters."""
    total = sum(sizes)
    return sum(m * m for m in sizes) / total if total else 0.0


def design_effect(sizes: Sequence[int], icc: float) -> float:
    """`1 + (m_eff - 1) * icc`."""
    return 1.0 + (effective_size(sizes) - 1.0) * icc


def anova_icc(successes: Sequence[Sequence[float]]) -> float | None:
    """The one-way ANOVA estimate of the intra-cluster correlation of per-episode outcomes,
    one sequence per cluster (unequal sizes), clipped at 0; None with fewer than 2 clusters
    or no variation."""
    groups = [list(g) for g in successes if len(g)]
    k = len(groups)
    n = sum(len(g) for g in groups)
    if k < 2 or n <= k:
        return None
    grand = sum(sum(g) for g in groups) / n
    between = sum(len(g) * (sum(g) / len(g) - grand) ** 2 for g in groups) / (k - 1)
    within = sum(sum((x - sum(g) / len(g)) ** 2 for x in g) for g in groups) / (n - k)
    m0 = (n - sum(len(g) ** 2 for g in groups) / n) / (k - 1)
    denominator = between + (m0 - 1.0) * within
    if denominator <= 0:
        return None
    return max(0.0, (between - within) / denominator)


__all__ = [
    "anova_icc",
    "clusters_needed",
    "design_effect",
    "effective_size",
    "minimal_detectable",
    "z_sum",
]
