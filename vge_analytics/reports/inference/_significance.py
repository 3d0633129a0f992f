"""Tests of a paired difference that respect clusters, and corrections for a family of tests
(docs/STATISTICS.md).

- The cluster sign-flip permutation test: under the null hypothesis that the two runs are
  exchangeable within each cluster (swapping A and B on all episodes of a device changes
  nothing in distribution), every pattern of swaps is as likely as the data. The p-value is
  the share of patterns whose |B - A| is at least the observed one: all 2^G patterns when
  there are few clusters (an exact test), else the observed pattern and R random ones,
  `(1 + #extreme) / (R + 1)`. Swapping a cluster swaps its sums of each run, so the test
  works for every pooled metric, not only for SR.
- The clustered McNemar test of success (Durkalski et al. 2003): with `D_g = b_g - c_g` the
  discordant episodes of cluster g solved by A only minus those solved by B only,
  `X2 = (sum D_g)^2 / sum D_g^2` is chi-square with one degree of freedom under the null
  (it is the normal approximation of the sign-flip test of success); with one episode per
  cluster it is McNemar's uncorrected statistic.
- Corrections: Holm's step-down (controls the family-wise error rate, no assumption on the
  dependence between tests) and Benjamini-Hochberg's step-up (the false discovery rate).
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence

import numpy as np

from ..._errors import AnalyticsError
from .._defaults import CORRECTIONS, DEFAULT_CORRECTION
from ._clusters import A_DEN, A_NUM, B_DEN, B_NUM, CHUNK, paired_difference

EXACT_CLUSTERS = 20
"""The most clusters whose every sign pattern is enumerated (when 2^G <= resamples)."""
_TIE = 1e-9
"""Relative tolerance under which a permuted statistic counts as equal to the observed."""


def _swap_delta(sums: np.ndarray, n_metrics: int) -> np.ndarray:
    """How the totals change when a cluster's runs swap: A gets B's sums and B gets A's."""
    delta = np.empty_like(sums)
    for i in range(n_metrics):
        j = 4 * i
        delta[:, j + A_NUM] = sums[:, j + B_NUM] - sums[:, j + A_NUM]
        delta[:, j + A_DEN] = sums[:, j + B_DEN] - sums[:, j + A_DEN]
        delta[:, j + B_NUM] = -delta[:, j + A_NUM]
        delta[:, j + B_DEN] = -delta[:, j + A_DEN]
    return delta


def _patterns(n_clusters: int, resamples: int, seed: int) -> tuple[bool, Iterator[np.ndarray]]:
    """(exact, chunks of swap patterns): every pattern when 2^G <= resamples, else `resamples`
    random ones from a generator of its own (seeded by (seed, 1): not the bootstrap's)."""
    if n_clusters <= EXACT_CLUSTERS and 2**n_clusters <= resamples:
        codes = np.arange(2**n_clusters, dtype=np.int64)
        every = ((codes[:, None] >> np.arange(n_clusters)) & 1).astype(np.float64)
        return True, iter(np.array_split(every, max(1, len(every) // CHUNK)))

    def random() -> Iterator[np.ndarray]:
        rng = np.random.default_rng([seed, 1])
        done = 0
        while done < resamples:
            size = min(CHUNK, resamples - done)
            yield rng.integers(0, 2, size=(size, n_clusters)).astype(np.float64)
            done += size

    return False, random()


def sign_flip_p(
    sums: np.ndarray, scales: Sequence[float], seed: int, resamples: int
) -> tuple[np.ndarray, bool]:
    """(two-sided p-value of B - A per metric, whether it is exact) from the (G x 4m)
    cluster sums of a pair; NaN where the observed difference is not defined. A pattern
    whose difference is not defined (an empty denominator) counts as extreme."""
    n_metrics = len(scales)
    totals = sums.sum(axis=0)
    observed = np.abs(paired_difference(totals, scales))
    bar = observed - _TIE * np.maximum(1.0, observed)
    delta = _swap_delta(sums, n_metrics)
    exact, chunks = _patterns(sums.shape[0], resamples, seed)
    extreme = np.zeros(n_metrics)
    count = 0
    for flips in chunks:
        permuted = np.abs(paired_difference(totals + flips @ delta, scales))
        extreme += (~(permuted < bar)).sum(axis=0)  # NaN compares False: counted
        count += len(flips)
    p = extreme / count if exact else (1.0 + extreme) / (count + 1.0)
    return np.where(np.isnan(observed), np.nan, np.minimum(p, 1.0)), exact


def check_correction(correction: str) -> str:
    if correction not in CORRECTIONS:
        raise AnalyticsError(
            f"unknown correction {correction!r}; choose one of {', '.join(CORRECTIONS)}"
        )
    return correction


def test_name(n_clusters: int, exact: bool, resamples: int) -> str:
    """How a p-value was computed, for a summary."""
    if n_clusters < 2:
        return "none (one cluster)"
    if exact:
        return f"cluster sign-flip, exact (all {2**n_clusters} patterns)"
    return f"cluster sign-flip, {resamples} random patterns"


def clustered_mcnemar(a_only: np.ndarray, b_only: np.ndarray) -> float:
    """Durkalski's clustered McNemar p-value from the per-cluster discordant counts."""
    d = np.asarray(a_only, dtype=np.float64) - np.asarray(b_only, dtype=np.float64)
    spread = float(np.square(d).sum())
    if spread == 0.0:
        return 1.0
    statistic = float(d.sum()) ** 2 / spread
    return math.erfc(math.sqrt(statistic / 2.0))


def adjust_p(p_values: Sequence[float | None], method: str) -> list[float | None]:
    """The p-values adjusted for the family they form (`holm`, `bh` or `none`); a missing
    p-value (None or NaN) is not part of the family and stays None."""
    check_correction(method)
    present = [(float(p), i) for i, p in enumerate(p_values) if p is not None and not math.isnan(p)]
    out: list[float | None] = [None] * len(p_values)
    if method == "none":
        for p, i in present:
            out[i] = p
        return out
    ordered = sorted(present)  # ties keep their positions' order
    m = len(ordered)
    if method == "holm":
        running = 0.0
        for k, (p, i) in enumerate(ordered):
            running = max(running, min(1.0, (m - k) * p))
            out[i] = running
    else:  # Benjamini-Hochberg, from the largest p down
        running = 1.0
        for k in range(m - 1, -1, -1):
            p, i = ordered[k]
            running = min(running, m * p / (k + 1))
            out[i] = running
    return out


__all__ = [
    "adjust_p",
    "check_correction",
    "clustered_mcnemar",
    "CORRECTIONS",
    "DEFAULT_CORRECTION",
    "EXACT_CLUSTERS",
    "sign_flip_p",
    "test_name",
]
