"""pass@k and pass^k: by hand and equal to enumerating every k of the n runs."""

from __future__ import annotations

import itertools
from fractions import Fraction

import pytest

from vge_analytics.reports.inference import pass_at_k, pass_hat_k


def test_by_hand() -> None:
    """n = 3: c = 1 -> pass@2 = 1 - C(2,2)/C(3,2) = 2/3, pass^2 = 0; c = 2 -> pass@2 = 1,
    pass^2 = C(2,2)/C(3,2) = 1/3; pass@1 = pass^1 = c/n."""
    assert pass_at_k(3, 1, 2) == pytest.approx(2 / 3) and pass_hat_k(3, 1, 2) == 0.0
    assert pass_at_k(3, 2, 2) == 1.0 and pass_hat_k(3, 2, 2) == pytest.approx(1 / 3)
    assert pass_at_k(3, 2, 1) == pass_hat_k(3, 2, 1) == pytest.approx(2 / 3)
    assert pass_at_k(3, 0, 3) == 0.0 and pass_hat_k(3, 3, 3) == 1.0


@pytest.mark.parametrize("n", range(1, 8))
def test_equal_to_enumerating_every_k_subset(n: int) -> None:
    for c in range(n + 1):
        outcomes = [1] * c + [0] * (n - c)
        for k in range(1, n + 1):
            subsets = list(itertools.combinations(outcomes, k))
            any_ = Fraction(sum(max(s) for s in subsets), len(subsets))
            all_ = Fraction(sum(min(s) for s in subsets), len(subsets))
            assert pass_at_k(n, c, k) == float(any_)
            assert pass_hat_k(n, c, k) == float(all_)


def test_k_outside_one_to_n_is_refused() -> None:
    with pytest.raises(ValueError, match="k must be between 1 and the number of runs n = 3, not 4"):
        pass_at_k(3, 1, 4)
    with pytest.raises(ValueError, match="not 0"):
        pass_hat_k(3, 1, 0)
