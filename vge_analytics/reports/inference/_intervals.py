"""A metric's 95% interval per group (the Leaderboard's): the group's clusters resampled with
replacement (devices by default), each resample's metric pooled from the drawn episodes'
terms; beside it the clustered (CR1) and naive standard errors and the design effect
(docs/STATISTICS.md)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import polars as pl

from replay.io import EPISODES_TABLE

from ...metrics import MetricsSource, episode_terms, metric_set
from ...store import Filters, check_columns, episodes, open_store, runs
from ._clusters import (
    DEFAULT_CLUSTER,
    bootstrap_totals,
    cluster_code_column,
    cluster_sums,
    cr1_variance,
    percentile_interval,
    pooled,
    ratio_contributions,
)
from ._paired import CLUSTER_COLUMNS, check_cluster, check_resampling, finite

INTERVAL_COLUMNS: dict[str, pl.DataType] = {
    "value": pl.Float64,
    "ci_low": pl.Float64,
    "ci_high": pl.Float64,
    "se": pl.Float64,
    "se_naive": pl.Float64,
    "deff": pl.Float64,
    "n_episodes": pl.Int64,
    "n_clusters": pl.Int64,
}


def _grouped_terms(
    store, metric: str, by: Sequence[str], where: Filters, available
) -> pl.DataFrame:
    """One row per (run, episode) with the group columns, the cluster columns, num and den."""
    terms = episode_terms(store, [metric], where, metrics_dir=available)
    wanted = ["run_id", "episode_id", "device_id", "category"]
    on_episodes = [c for c in by if store.has_column(EPISODES_TABLE, c) and c not in wanted]
    rows = episodes(store, where, columns=[*wanted, *on_episodes])
    on_runs = [c for c in by if c not in wanted and c not in on_episodes]
    if on_runs:
        rows = rows.join(runs(store).select("run_id", *on_runs), on="run_id", how="left")
    return rows.join(terms, on=["run_id", "episode_id"], how="inner")


def metric_intervals(
    out,
    *,
    metric: str = "SR",
    by: Sequence[str] = ("run_id",),
    where: Filters = None,
    cluster: str = DEFAULT_CLUSTER,
    seed: int = 0,
    resamples: int = 2000,
    metrics_dir: MetricsSource = None,
) -> pl.DataFrame:
    """<by columns>, value, ci_low, ci_high, se, se_naive, deff, n_episodes, n_clusters: one
    row per group (sorted by the group values, nulls last). A group of one cluster has no
    interval and no SE (null)."""
    store = open_store(out)
    check_resampling(seed, resamples)
    check_cluster(cluster)
    by = list(by)
    check_columns(store, by, [EPISODES_TABLE], "grouping")
    available = metric_set(metrics_dir)
    (chosen,) = available.resolve([metric])
    frame = _grouped_terms(store, chosen.name, by, where, available)
    num, den = f"{chosen.name}:num", f"{chosen.name}:den"
    code = cluster_code_column(CLUSTER_COLUMNS[cluster], by)  # each group's cluster codes
    groups = (
        frame.sort([*by, "run_id", "episode_id"], nulls_last=True)
        .with_columns(code)
        .partition_by(by, maintain_order=True, as_dict=True)
    )
    keys, sums, naive = [], [], []
    for key, part in groups.items():
        values = np.ascontiguousarray(part.select(num, den).to_numpy(), dtype=np.float64)
        codes = part[code.meta.output_name()].to_numpy().astype(np.int64)
        keys.append(key)
        sums.append(cluster_sums(values.reshape(part.height, 2), codes, int(codes.max()) + 1))
        naive.append(values.reshape(part.height, 2))
    usable = [i for i, s in enumerate(sums) if s.shape[0] >= 2]
    boots = dict(
        zip(usable, bootstrap_totals([sums[i] for i in usable], seed, resamples), strict=True)
    )
    rows = []
    for i, key in enumerate(keys):
        s, e = sums[i], naive[i]
        value = finite(pooled(e[:, 0].sum(), e[:, 1].sum(), chosen.scale))
        se = finite(
            np.sqrt(cr1_variance(ratio_contributions(s[:, 0], s[:, 1], chosen.scale)[:, None]))[0]
        )
        se_naive = finite(
            np.sqrt(cr1_variance(ratio_contributions(e[:, 0], e[:, 1], chosen.scale)[:, None]))[0]
        )
        low, high = (None, None)
        if i in boots and value is not None:
            low, high = percentile_interval(pooled(boots[i][:, 0], boots[i][:, 1], chosen.scale))
        rows.append(
            dict(zip(by, key, strict=True))
            | {
                "value": value,
                "ci_low": low,
                "ci_high": high,
                "se": se,
                "se_naive": se_naive,
                "deff": se**2 / se_naive**2 if se is not None and se_naive else None,
                "n_episodes": e.shape[0],
                "n_clusters": s.shape[0],
            }
        )
    schema = {c: frame.schema[c] for c in by} | INTERVAL_COLUMNS
    return pl.DataFrame(rows, schema=schema, orient="row")


__all__ = ["INTERVAL_COLUMNS", "metric_intervals"]
