"""Clusters of episodes, the cluster bootstrap and the clustered (CR1) standard error of a
paired difference of pooled metrics (docs/STATISTICS.md).

Every metric is pooled, `scale * sum(num) / sum(den)` over the episodes of a group, so a
group's value is a function of the sums of its episodes' terms, and the sums over a set of
clusters are sums of per-cluster sums. Everything here works on per-cluster sums: an
(G x k) matrix whose columns are, per metric, the numerator and denominator of run A and of
run B (`A_NUM, A_DEN, B_NUM, B_DEN`).
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence

import numpy as np
import polars as pl

from .._defaults import CLUSTER_UNITS, DEFAULT_CLUSTER

A_NUM, A_DEN, B_NUM, B_DEN = range(4)
"""Columns of one metric in a matrix of paired sums."""
CHUNK = 250
"""Resamples drawn at a time (bounds the memory of a draw to CHUNK x G counts)."""


def cluster_codes(labels: Sequence[str]) -> tuple[np.ndarray, list[str]]:
    """(code of each label in 0..G-1, the G distinct labels sorted): cluster g is the g-th
    label in sorted order, so the order of the rows never changes a result."""
    names, codes = np.unique(np.asarray(labels, dtype=object).astype(str), return_inverse=True)
    return codes.reshape(-1).astype(np.int64), [str(n) for n in names]


def cluster_code_column(column: str, over: Sequence[str]) -> pl.Expr:
    """The codes `cluster_codes` gives the labels of `column` within each group of `over`, as
    one expression over a whole frame (no Python string per row): the label's place among the
    group's distinct labels in sorted order (UTF-8 byte order is code point order, numpy's),
    a null counted as the label `None`, as `cluster_codes` reads it."""
    label = pl.col(column).cast(pl.String).fill_null("None")
    ranked = label.rank("dense").over(over) if over else label.rank("dense")
    return (ranked.cast(pl.Int64) - 1).alias(f"{column}:cluster")


def float_matrix(frame: pl.DataFrame, columns: Sequence[str]) -> np.ndarray:
    """`columns` of `frame` as a C-ordered (rows x columns) float64 matrix, each cast to
    Float64 by polars first. A sum of integers is a HUGEINT, read as a 128-bit decimal:
    converted by numpy it became a Python `Decimal` per value, then a float (GVPE's two terms
    of 9.3 million episodes at 100x: 26 s); polars' cast rounds each value to the nearest
    double as `float(Decimal)` does, so the matrix is the same bits (tests)."""
    cast = frame.select(pl.col(c).cast(pl.Float64) for c in columns)
    # (made in C order by polars: a copy of a column-major array took 0.6 s at 100x)
    return np.ascontiguousarray(cast.to_numpy(order="c"), dtype=np.float64)


def cluster_sums(values: np.ndarray, codes: np.ndarray, n_clusters: int) -> np.ndarray:
    """Per-cluster column sums of an (n x k) matrix: (G x k). A column at a time by
    `np.bincount`, which adds the rows in their order as `np.add.at` does (the same bits),
    several times faster (900 groups of 10,000 rows at 100x: 0.1 s, not 0.4 to 0.7)."""
    values = np.asarray(values, dtype=np.float64)
    out = np.empty((n_clusters, values.shape[1]), dtype=np.float64)
    for j in range(values.shape[1]):
        out[:, j] = np.bincount(codes, weights=values[:, j], minlength=n_clusters)
    return out


def pooled(num: np.ndarray, den: np.ndarray, scale: float | np.ndarray) -> np.ndarray:
    """`scale * num / den`, NaN where the denominator is not positive (an empty metric)."""
    num, den = np.asarray(num, dtype=np.float64), np.asarray(den, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(den > 0, scale * num / np.where(den > 0, den, 1.0), np.nan)


def paired_difference(totals: np.ndarray, scales: Sequence[float]) -> np.ndarray:
    """B - A of each metric from totals (... x 4m): `pooled(B) - pooled(A)` per metric."""
    parts = []
    for i, scale in enumerate(scales):
        j = 4 * i
        a = pooled(totals[..., j + A_NUM], totals[..., j + A_DEN], scale)
        b = pooled(totals[..., j + B_NUM], totals[..., j + B_DEN], scale)
        parts.append(b - a)
    return np.stack(parts, axis=-1)


def cluster_draws(n_clusters: int, resamples: int, seed: int) -> Iterator[np.ndarray]:
    """Multinomial cluster counts, CHUNK resamples at a time: resample r draws G clusters
    with replacement and row r counts how often each was drawn."""
    rng = np.random.default_rng(seed)
    even = np.full(n_clusters, 1.0 / n_clusters)
    done = 0
    while done < resamples:
        size = min(CHUNK, resamples - done)
        yield rng.multinomial(n_clusters, even, size=size).astype(np.float64)
        done += size


def bootstrap_totals(sums: Sequence[np.ndarray], seed: int, resamples: int) -> list[np.ndarray]:
    """For each (G_i x k_i) matrix of cluster sums, the (R x k_i) totals of R resamples of
    its clusters with replacement. The generator starts at `seed` for each number of
    clusters, so every matrix with G clusters gets the same draws (the two runs of a pair,
    every metric, and every pair with as many clusters: drawn once for all of them)."""
    out: list[np.ndarray | None] = [None] * len(sums)
    by_size: dict[int, list[int]] = {}
    for i, s in enumerate(sums):
        by_size.setdefault(s.shape[0], []).append(i)
    for size, members in sorted(by_size.items()):
        totals = {i: np.empty((resamples, sums[i].shape[1])) for i in members}
        done = 0
        for counts in cluster_draws(size, resamples, seed):
            for i in members:  # one product per matrix: its result never depends on the others
                totals[i][done : done + len(counts)] = counts @ sums[i]
            done += len(counts)
        for i in members:
            out[i] = totals[i]
    return [o for o in out if o is not None]


def percentile_interval(draws: np.ndarray) -> tuple[float | None, float | None]:
    """The 2.5th and 97.5th percentiles of the finite draws (None, None without any)."""
    finite = draws[np.isfinite(draws)]
    if not finite.size:
        return None, None
    low, high = np.percentile(finite, [2.5, 97.5])
    return float(low), float(high)


def ratio_contributions(num: np.ndarray, den: np.ndarray, scale: float) -> np.ndarray:
    """Each row's contribution to a pooled ratio `scale * sum(num) / sum(den)`, linearised
    (the delta method): `scale * (num_g - R den_g) / D` with `R = N / D` the totals' ratio.
    Their sum is 0; their CR1 variance is the ratio's. NaN where the denominator is empty."""
    total_den = float(den.sum())
    if total_den <= 0:
        return np.full(num.shape[0], np.nan)
    ratio = float(num.sum()) / total_den
    return scale * (num - ratio * den) / total_den


def linearized(sums: np.ndarray, scales: Sequence[float]) -> np.ndarray:
    """Each row's contribution to the paired difference B - A of each metric, linearised:
    `ratio_contributions` of B minus those of A. For SR (every denominator 1) it is
    `(d_g - mean(d)) / n` summed over the row's episodes, d the per-episode difference."""
    cols = []
    for i, scale in enumerate(scales):
        j = 4 * i
        b = ratio_contributions(sums[:, j + B_NUM], sums[:, j + B_DEN], scale)
        a = ratio_contributions(sums[:, j + A_NUM], sums[:, j + A_DEN], scale)
        cols.append(b - a)
    return np.column_stack(cols) if cols else np.empty((sums.shape[0], 0))


def cr1_variance(contributions: np.ndarray) -> np.ndarray:
    """The sandwich variance with the CR1 small-sample factor, from per-cluster sums of the
    linearised contributions (G x m): `G / (G - 1) * sum_g e_g^2`; NaN with fewer than two
    clusters. With each episode its own cluster it is the naive (independent) variance."""
    n = contributions.shape[0]
    if n < 2:
        return np.full(contributions.shape[1], np.nan)
    return n / (n - 1) * np.square(contributions).sum(axis=0)


__all__ = [
    "A_DEN",
    "A_NUM",
    "B_DEN",
    "B_NUM",
    "bootstrap_totals",
    "CLUSTER_UNITS",
    "cluster_code_column",
    "cluster_codes",
    "cluster_draws",
    "cluster_sums",
    "cr1_variance",
    "float_matrix",
    "DEFAULT_CLUSTER",
    "linearized",
    "paired_difference",
    "percentile_interval",
    "pooled",
    "ratio_contributions",
]
