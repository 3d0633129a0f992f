"""Ranks of groups by a metric, and Kendall's tau-b between two rankings (`vge rescore`).

Ranks. Rank 1 is the best value in the metric's direction (the highest when higher is better,
the lowest when lower is better). Values equal after rounding to 9 decimals (the rule the
bold marks of the tables use) are ties and share the best rank of their block; the next
rank skips as many places ("competition" ranking: 1, 2, 2, 4). A null or NaN value (an empty
group) has no rank.

Kendall's tau-b. Over the n groups that have a rank in both rankings x and y, a pair (i, j)
is *concordant* when x and y order it the same way (sign(x_i - x_j) * sign(y_i - y_j) = 1)
and *discordant* when they order it the opposite ways (the product is -1); a pair tied in x
or in y is neither. With C and D those counts, n0 = n(n - 1)/2 pairs, n1 = the pairs tied in
x (sum over the blocks of ties of x of t(t - 1)/2) and n2 = the pairs tied in y::

    tau_b = (C - D) / sqrt((n0 - n1) * (n0 - n2))

It is 1 when both rankings agree on every pair, -1 when they reverse every pair, and null
when fewer than two groups are ranked in both or one ranking ties them all (no pair is
ordered). tau-b, not tau-a = (C - D) / n0, because metrics tie often (SR of two runs that
solve as many episodes): tau-a counts a tie as a disagreement, so two identical rankings
with a tie would score below 1; tau-b corrects the denominator for the ties of each ranking
and gives exactly 1.

`kendall_tau_b_pairs` computes it from that definition, pair by pair (O(n^2)): the reference.
`kendall_tau_b` computes the same number in O(n log n) (Knight's method: sort by (x, y),
count the discordant pairs as the inversions of y, and the ties by runs of equal values); the
tests check the two agree.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Sequence

import numpy as np

TIE_DECIMALS = 9
"""Values equal at this many decimals are ties."""


def competition_ranks(values: Sequence[float | None], higher_is_better: bool) -> list[int | None]:
    """The rank of each value (1 = best in the direction; ties share a rank; null: None)."""
    keyed = {
        i: round(v, TIE_DECIMALS)
        for i, v in enumerate(values)
        if v is not None and not math.isnan(v)
    }
    ordered = sorted(set(keyed.values()), reverse=higher_is_better)
    counts = Counter(keyed.values())
    first: dict[float, int] = {}
    position = 1
    for v in ordered:
        first[v] = position
        position += counts[v]
    return [first[keyed[i]] if i in keyed else None for i in range(len(values))]


def kendall_tau_b_pairs(x: Sequence[float], y: Sequence[float]) -> float | None:
    """tau-b from its definition, pair by pair (the reference; see the module docstring)."""
    n = len(x)
    if len(y) != n:
        raise ValueError("x and y must have the same length")
    concordant = discordant = tied_x = tied_y = 0
    for i in range(n):
        for j in range(i + 1, n):
            dx = (x[i] > x[j]) - (x[i] < x[j])
            dy = (y[i] > y[j]) - (y[i] < y[j])
            tied_x += dx == 0
            tied_y += dy == 0
            concordant += dx * dy == 1
            discordant += dx * dy == -1
    n0 = n * (n - 1) // 2
    denominator = (n0 - tied_x) * (n0 - tied_y)
    if denominator == 0:
        return None
    return (concordant - discordant) / math.sqrt(denominator)


def _tied_pairs(values: np.ndarray) -> int:
    """Pairs of equal values: the sum over runs of equal values of t(t - 1)/2."""
    _, counts = np.unique(values, return_counts=True, axis=0)
    return int((counts * (counts - 1) // 2).sum())


def _inversions(codes: np.ndarray) -> int:
    """Pairs i < j with codes[i] > codes[j] (codes: integers in 0..n-1), by a bottom-up merge
    sort whose every level is counted with one vectorised binary search."""
    n = len(codes)
    values = codes.astype(np.int64)
    index = np.arange(n)
    total = 0
    width = 1
    while width < n:
        block = index // (2 * width)
        right = index % (2 * width) >= width
        keys = block * n + values  # sorted inside each half-block, blocks in order
        left_keys, left_block = keys[~right], block[~right]
        # For each element of a right half: the elements of its left half that are larger.
        ends = np.searchsorted(left_block, block[right], side="right")
        not_larger = np.searchsorted(left_keys, keys[right], side="right")
        total += int((ends - not_larger).sum())
        values = values[np.lexsort((values, block))]  # merge: sort inside each block
        width *= 2
    return total


def kendall_tau_b(x: Sequence[float], y: Sequence[float]) -> float | None:
    """tau-b in O(n log n): the same number as `kendall_tau_b_pairs`."""
    n = len(x)
    if len(y) != n:
        raise ValueError("x and y must have the same length")
    if n < 2:
        return None
    xa, ya = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    order = np.lexsort((ya, xa))  # by x, then y
    xs, ys = xa[order], ya[order]
    n0 = n * (n - 1) // 2
    tied_x = _tied_pairs(xs)
    tied_y = _tied_pairs(ys)
    tied_both = _tied_pairs(np.column_stack((xs, ys)))
    # Inside a run of equal x, y is sorted: no inversion there, so the inversions of y are
    # exactly the pairs ordered one way by x and the other by y.
    codes = np.unique(ys, return_inverse=True)[1].reshape(-1)
    discordant = _inversions(codes)
    concordant = n0 - tied_x - tied_y + tied_both - discordant
    denominator = (n0 - tied_x) * (n0 - tied_y)
    if denominator == 0:
        return None
    return (concordant - discordant) / math.sqrt(denominator)


__all__ = ["TIE_DECIMALS", "competition_ranks", "kendall_tau_b", "kendall_tau_b_pairs"]
