"""pass@k and pass^k of an episode played n times with c successes (docs/STATISTICS.md).

- pass@k, the chance that at least one of k runs drawn without replacement from the n
  succeeds: `1 - C(n - c, k) / C(n, k)` (the unbiased estimator of Chen et al. 2021);
- pass^k, the chance that all k succeed: `C(c, k) / C(n, k)` (the unbiased estimator of
  the reliability measure of tau-bench, Yao et al. 2024).

Both are computed from exact integers (`math.comb`) and averaged over episodes; for k = 1
both are c / n, the mean success.
"""

from __future__ import annotations

from fractions import Fraction
from math import comb


def _check(n: int, c: int, k: int) -> None:
    if not 1 <= k <= n:
        raise ValueError(f"k must be between 1 and the number of runs n = {n}, not {k}")
    if not 0 <= c <= n:
        raise ValueError(f"successes c must be between 0 and n = {n}, not {c}")


def pass_at_k(n: int, c: int, k: int) -> float:
    """`1 - C(n - c, k) / C(n, k)`."""
    _check(n, c, k)
    return float(1 - Fraction(comb(n - c, k), comb(n, k)))


def pass_hat_k(n: int, c: int, k: int) -> float:
    """`C(c, k) / C(n, k)`."""
    _check(n, c, k)
    return float(Fraction(comb(c, k), comb(n, k)))


__all__ = ["pass_at_k", "pass_hat_k"]
