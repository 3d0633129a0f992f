"""`vge power`: how large a difference a comparison can detect, and how many devices (and
episodes) it needs to detect a given one (docs/STATISTICS.md; the formulas in `_power`).

- From two runs: the clustered SE of their paired difference on the common episodes gives
  the minimal detectable difference with those episodes, and the clusters needed for
  `delta` (as many episodes per cluster as now).
- For planning, from no run at all: the benchmark's cluster sizes (the episodes OUT holds
  per device), a success rate, and an intra-cluster correlation (`icc`, given, else measured
  on OUT's runs: the median over the runs of the one-way ANOVA estimate of the correlation
  of success within a cluster).
"""

from __future__ import annotations

import math

import numpy as np
import polars as pl

from ..._errors import AnalyticsError
from ...metrics import MetricsSource, metric_set
from ...store import check_same_benchmark, open_store, run_query
from .._defaults import DEFAULT_DELTA, DEFAULT_POWER
from ._clusters import DEFAULT_CLUSTER
from ._paired import (
    CLUSTER_COLUMNS,
    check_cluster,
    entity_terms,
    finite,
    pair,
    pair_statistics,
    runs_of,
)
from ._power import (
    anova_icc,
    clusters_needed,
    design_effect,
    effective_size,
    minimal_detectable,
    z_sum,
)


def _check(delta: float, alpha: float, power: float) -> None:
    if not delta > 0 or not math.isfinite(delta):
        raise AnalyticsError(f"--delta must be a positive difference to detect, not {delta:g}")
    if not 0.0 < alpha < 1.0:
        raise AnalyticsError(f"--alpha must be between 0 and 1, not {alpha:g}")
    if not 0.0 < power < 1.0:
        raise AnalyticsError(f"--power must be between 0 and 1, not {power:g}")


def power_of_pair(
    out,
    run_a: str,
    run_b: str,
    *,
    metric: str = "SR",
    delta: float = DEFAULT_DELTA,
    alpha: float = 0.05,
    power: float = DEFAULT_POWER,
    cluster: str = DEFAULT_CLUSTER,
    metrics_dir: MetricsSource = None,
    allow_different_benchmarks: bool = False,
) -> pl.DataFrame:
    """One row: the pair's observed difference and clustered SE, the minimal detectable
    difference with its common episodes, and the clusters and episodes needed for `delta`
    (null, with a note, when the pair has fewer than two clusters or never differs).

    `allow_different_benchmarks`: compare runs replayed against different benchmarks (refused
    by default, `DifferentBenchmarksError`: their episodes share ids, not tasks)."""
    _check(delta, alpha, power)
    check_cluster(cluster)
    store = open_store(out)
    runs_of(store, [run_a, run_b])
    check_same_benchmark(store, [run_a, run_b], allow=allow_different_benchmarks)
    available = metric_set(metrics_dir)
    (chosen,) = available.resolve([metric])
    terms = entity_terms(store, {run_a: [run_a], run_b: [run_b]}, [chosen], available)
    paired = pair(terms, run_a, run_b, [chosen], cluster)
    if not paired.episodes:
        raise AnalyticsError(f"runs {run_a!r} and {run_b!r} have no episode in common")
    (stats,) = pair_statistics([paired], [chosen.scale], 0, 1)
    n, g = len(paired.episodes), len(paired.clusters)
    se = finite(stats.se[0])
    note = None
    if se is None:
        note = f"the common episodes are all in one {cluster}: no clustered SE to plan from"
    elif se == 0:
        note = "the runs never differ on the common episodes: no spread to plan from"
    usable = se is not None and se > 0
    needed = clusters_needed(se, g, delta, alpha, power) if usable else None
    row = {
        "metric": chosen.name,
        "run_a": run_a,
        "run_b": run_b,
        "cluster": cluster,
        "n_common": n,
        "n_clusters": g,
        "episodes_per_cluster": n / g,
        "diff": finite(stats.diff[0]),
        "se": se,
        "deff": finite(stats.deff[0]),
        "alpha": alpha,
        "power": power,
        "mde": minimal_detectable(se, alpha, power) if se is not None else None,
        "delta": delta,
        "clusters_needed": needed,
        "episodes_needed": math.ceil(needed * n / g) if needed is not None else None,
        "note": note,
    }
    return pl.DataFrame([row], schema_overrides=_NULLABLE)


_NULLABLE = {
    "se": pl.Float64,
    "deff": pl.Float64,
    "mde": pl.Float64,
    "icc": pl.Float64,
    "clusters_needed": pl.Int64,
    "episodes_needed": pl.Int64,
    "note": pl.String,
}


_EPISODES = "SELECT run_id, episode_id, device_id, category, success FROM episodes"


def _cluster_sizes(episodes: pl.DataFrame, cluster: str) -> list[int]:
    """The distinct episodes of each cluster (over every run), in cluster order."""
    column = CLUSTER_COLUMNS[cluster]
    sizes = episodes.group_by(column).agg(pl.col("episode_id").n_unique().alias("m")).sort(column)
    return [int(m) for m in sizes["m"]]


def measured_icc(episodes: pl.DataFrame, cluster: str) -> tuple[float | None, int]:
    """(median over the runs of the ANOVA ICC of success within clusters, runs measured)
    from an episodes frame (run_id, episode_id, success and the cluster column)."""
    column = CLUSTER_COLUMNS[cluster]
    grouped = (
        episodes.sort("run_id", column, "episode_id")
        .group_by("run_id", column, maintain_order=True)
        .agg(pl.col("success").cast(pl.Float64))
    )
    values = []
    for part in grouped.partition_by("run_id", maintain_order=True):
        icc = anova_icc(part["success"].to_list())
        if icc is not None:
            values.append(icc)
    if not values:
        return None, 0
    return float(np.median(values)), len(values)


def plan(
    out,
    *,
    rate: float,
    delta: float = DEFAULT_DELTA,
    icc: float | None = None,
    alpha: float = 0.05,
    power: float = DEFAULT_POWER,
    cluster: str = DEFAULT_CLUSTER,
) -> pl.DataFrame:
    """One row planning a comparison of success rates `rate` and `rate + delta` points on a
    benchmark clustered as OUT's (see the module docstring)."""
    _check(delta, alpha, power)
    check_cluster(cluster)
    if not 0.0 < rate < 1.0:
        raise AnalyticsError(
            f"--rate is a success rate between 0 and 1 (0.5 for 50%), not {rate:g}"
        )
    other = rate + delta / 100.0
    if other >= 1.0:
        raise AnalyticsError(f"--rate {rate:g} plus --delta {delta:g} points passes 100%")
    episodes = run_query(open_store(out), _EPISODES, [])
    sizes = _cluster_sizes(episodes, cluster)
    if not sizes:
        raise AnalyticsError(f"{open_store(out).out} holds no episode to take cluster sizes from")
    source = "given"
    if cluster == "episode":
        icc, source = 0.0, "none (episodes are independent)"
    elif icc is None:
        icc, runs_used = measured_icc(episodes, cluster)
        if icc is None:
            raise AnalyticsError(f"no run of OUT measures an ICC across two {cluster}s: give --icc")
        source = f"measured (median of {runs_used} runs)"
    elif not 0.0 <= icc <= 1.0:
        raise AnalyticsError(f"--icc must be between 0 and 1, not {icc:g}")
    variance = rate * (1 - rate) + other * (1 - other)
    deff = design_effect(sizes, icc)
    n_total = sum(sizes)
    per_cluster = n_total / len(sizes)
    needed = math.ceil(deff * z_sum(alpha, power) ** 2 * variance / (delta / 100.0) ** 2 - 1e-9)
    row = {
        "rate": rate,
        "delta": delta,
        "alpha": alpha,
        "power": power,
        "cluster": cluster,
        "n_clusters": len(sizes),
        "n_episodes": n_total,
        "episodes_per_cluster": per_cluster,
        "effective_cluster_size": effective_size(sizes),
        "icc": icc,
        "icc_source": source,
        "deff": deff,
        "mde": 100.0 * minimal_detectable(math.sqrt(deff * variance / n_total), alpha, power),
        "episodes_needed": needed,
        "clusters_needed": max(2, math.ceil(needed / per_cluster - 1e-9)),
    }
    return pl.DataFrame([row], schema_overrides=_NULLABLE)


__all__ = ["DEFAULT_DELTA", "DEFAULT_POWER", "measured_icc", "plan", "power_of_pair"]
