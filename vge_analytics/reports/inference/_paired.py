"""Two runs (or two sets of runs) on their common episodes, and the statistics of their
paired difference for every metric: the cluster bootstrap interval, the clustered and the
naive standard errors, the design effect and the sign-flip p-value (docs/STATISTICS.md).

An *entity* is a set of runs (one run for `vge compare A B`; every run of a model with
`--by model`): its term of an episode is the sum of its runs' terms there, so its metric is
the one `vge metrics --by` pools over those runs.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import polars as pl

from replay.io import RUNS_TABLE

from ..._errors import AnalyticsError, UnknownColumnError
from ...metrics import Metric, MetricSet, episode_terms
from ...store import Store, check_runs, run_query, runs
from ._clusters import (
    A_DEN,
    A_NUM,
    B_DEN,
    B_NUM,
    CLUSTER_UNITS,
    bootstrap_totals,
    cluster_codes,
    cluster_sums,
    cr1_variance,
    float_matrix,
    linearized,
    paired_difference,
    percentile_interval,
    pooled,
)
from ._significance import sign_flip_p

CLUSTER_COLUMNS: dict[str, str] = {
    "device": "device_id",
    "category": "category",
    "episode": "episode_id",
}
"""The episodes-table column naming each episode's cluster, per unit."""


def check_cluster(cluster: str) -> str:
    if cluster not in CLUSTER_UNITS:
        raise AnalyticsError(
            f"unknown cluster {cluster!r}; choose one of {', '.join(CLUSTER_UNITS)}"
        )
    return cluster


MAX_RESAMPLES = 100_000
"""The most resamples (and random sign patterns) a computation draws: the draws' totals are
held in memory, resamples x columns doubles."""


def check_resampling(seed: int, resamples: int) -> None:
    if not 1 <= resamples <= MAX_RESAMPLES:
        raise AnalyticsError(f"resamples must be between 1 and {MAX_RESAMPLES:,}, not {resamples}")
    if seed < 0:
        raise AnalyticsError(f"the seed must be 0 or more, not {seed}")


def runs_of(
    store: Store,
    chosen: Sequence[str] | None = None,
    columns: Sequence[str] = (),
    option: str = "--by",
) -> pl.DataFrame:
    """The runs table (OUT's runs, or the `chosen` ones), after checking that each chosen run
    is in OUT and each of `columns` is a scalar column of the runs table (named by `option`
    in the error)."""
    table = runs(store)
    check_runs(store, chosen or ())
    for column in columns:
        if column not in table.columns or not store.is_scalar(RUNS_TABLE, column):
            raise UnknownColumnError(
                f"{option} {column!r} is not a column of the runs table (run_id, model, "
                "agent_kind, lambda, meta_ columns)"
            )
    return table if chosen is None else table.filter(pl.col("run_id").is_in(list(chosen)))


def entity_terms(
    store: Store,
    entities: Mapping[str, Sequence[str]],
    chosen: Sequence[Metric],
    available: MetricSet,
) -> pl.DataFrame:
    """One row per (entity, episode it played): entity, episode_id, device_id, category and
    each metric's `name:num`, `name:den`, summed over the entity's runs."""
    owner = {run: name for name, runs in entities.items() for run in runs}
    runs = sorted(owner)
    terms = episode_terms(
        store, [m.name for m in chosen], where={"run_id": runs}, metrics_dir=available
    )
    where = run_query(
        store,
        "SELECT run_id, episode_id, device_id, category FROM episodes "
        "WHERE run_id IN (SELECT unnest(CAST(? AS VARCHAR[])))",
        [runs],
    )
    cols = [f"{m.name}:{part}" for m in chosen for part in ("num", "den")]
    return (
        where.join(terms, on=["run_id", "episode_id"], how="left")
        .with_columns(
            pl.col("run_id").replace_strict(owner, return_dtype=pl.String).alias("entity"),
            *[pl.col(c).cast(pl.Float64).fill_null(0.0) for c in cols],
        )
        .group_by("entity", "episode_id", "device_id", "category")
        .agg(*[pl.col(c).sum() for c in cols])
        .sort("entity", "episode_id")
    )


@dataclass(frozen=True)
class Paired:
    """Two entities on their common episodes (sorted by id)."""

    episodes: list[str]
    matrix: np.ndarray
    """(n x 4m): per metric the numerator and denominator of A, then of B."""
    codes: np.ndarray
    """Each episode's cluster, 0..G-1."""
    clusters: list[str]
    sums: np.ndarray
    """(G x 4m): the matrix summed per cluster."""


def pair(terms: pl.DataFrame, a: str, b: str, chosen: Sequence[Metric], cluster: str) -> Paired:
    """Entities `a` and `b` of an `entity_terms` frame, on the episodes both have."""
    return pair_frames(
        terms.filter(pl.col("entity") == a), terms.filter(pl.col("entity") == b), chosen, cluster
    )


def pair_frames(
    left: pl.DataFrame, right: pl.DataFrame, chosen: Sequence[Metric], cluster: str
) -> Paired:
    """Two entities' rows of an `entity_terms` frame (A's, B's), on their common episodes."""
    cols = [f"{m.name}:{part}" for m in chosen for part in ("num", "den")]
    right = right.select("episode_id", *cols)
    joined = left.drop("entity").join(right, on="episode_id", suffix="~b").sort("episode_id")
    order = [
        name
        for m in chosen
        for name in (f"{m.name}:num", f"{m.name}:den", f"{m.name}:num~b", f"{m.name}:den~b")
    ]
    # C order: numpy sums its rows one after another, as compare always has (a column-major
    # copy is summed pairwise, and the values would change in their last bits)
    matrix = float_matrix(joined, order)
    matrix = matrix.reshape(joined.height, len(order))
    codes, clusters = cluster_codes(joined[CLUSTER_COLUMNS[cluster]].to_list())
    return Paired(
        joined["episode_id"].to_list(),
        matrix,
        codes,
        clusters,
        cluster_sums(matrix, codes, len(clusters)),
    )


@dataclass(frozen=True)
class PairStatistics:
    """Per metric: values of A and B, B - A, and its uncertainty."""

    a: np.ndarray
    b: np.ndarray
    diff: np.ndarray
    ci_low: list[float | None]
    ci_high: list[float | None]
    se: np.ndarray
    """The clustered (CR1) standard error of B - A."""
    se_naive: np.ndarray
    """The standard error were the episodes independent."""
    p_value: np.ndarray
    """The cluster sign-flip p-value of B - A."""
    exact: bool
    """Whether every sign pattern was enumerated."""

    @property
    def deff(self) -> np.ndarray:
        """The design effect: clustered variance over the naive one."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(
                self.se_naive > 0, np.square(self.se) / np.square(self.se_naive), np.nan
            )


def pair_statistics(
    pairs: Sequence[Paired], scales: Sequence[float], seed: int, resamples: int
) -> list[PairStatistics]:
    """The statistics of each pair. A pair with fewer than two clusters gets no interval, SE
    or p-value (NaN / None): one cluster says nothing about the spread between clusters."""
    usable = [p for p in pairs if len(p.clusters) >= 2]
    boots = iter(bootstrap_totals([p.sums for p in usable], seed, resamples))
    out = []
    for p in pairs:
        totals = p.matrix.sum(axis=0)
        values = _values(totals, scales)
        nan = np.full(len(scales), np.nan)
        if len(p.clusters) < 2:
            out.append(
                PairStatistics(
                    *values, [None] * len(scales), [None] * len(scales), nan, nan, nan, False
                )
            )
            continue
        draws = paired_difference(next(boots), scales)
        bounds = [percentile_interval(draws[:, i]) for i in range(len(scales))]
        se = np.sqrt(cr1_variance(linearized(p.sums, scales)))
        se_naive = np.sqrt(cr1_variance(linearized(p.matrix, scales)))
        p_value, exact = sign_flip_p(p.sums, scales, seed, resamples)
        out.append(
            PairStatistics(
                *values,
                [lo for lo, _ in bounds],
                [hi for _, hi in bounds],
                se,
                se_naive,
                p_value,
                exact,
            )
        )
    return out


def _values(
    totals: np.ndarray, scales: Sequence[float]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A, B, B - A) per metric from the pair's totals."""
    j = 4 * np.arange(len(scales))
    s = np.asarray(scales, dtype=np.float64)
    a = pooled(totals[j + A_NUM], totals[j + A_DEN], s)
    b = pooled(totals[j + B_NUM], totals[j + B_DEN], s)
    return a, b, b - a


def finite(x: float | np.floating | None) -> float | None:
    """A number for a table: None for NaN, infinities and None."""
    return None if x is None or not np.isfinite(x) else float(x)


__all__ = [
    "check_cluster",
    "check_resampling",
    "CLUSTER_COLUMNS",
    "entity_terms",
    "finite",
    "MAX_RESAMPLES",
    "pair",
    "pair_frames",
    "pair_statistics",
    "Paired",
    "runs_of",
    "PairStatistics",
]
