"""A metric's 95% interval per group (the Leaderboard's): the group's clusters resampled with
replacement (devices by default), each resample's metric pooled from the drawn episodes'
terms; beside it the clustered (CR1) and naive standard errors and the design effect
(docs/STATISTICS.md)."""

from __future__ import annotations

from collections.abc import Iterator, Sequence

import numpy as np
import polars as pl

from replay.io import EPISODES_TABLE

from ...metrics import Metric, MetricsSource, episode_terms, metric_set
from ...store import (
    Filters,
    check_columns,
    episodes,
    kept_episode_terms,
    open_store,
    run_columns,
)
from ._clusters import (
    DEFAULT_CLUSTER,
    bootstrap_totals,
    cluster_code_column,
    cluster_sums,
    cr1_variance,
    float_matrix,
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
    store, metric: Metric, by: Sequence[str], where: Filters, available
) -> pl.DataFrame:
    """One row per (run, episode) with the group columns, the cluster columns, num and den:
    from the terms kept beside OUT where they answer (`store.kept_episode_terms`), else from
    the tables."""
    rows = kept_episode_terms(store, metric, by, where, files_of=available.files_of)
    if rows is None:
        terms = episode_terms(store, [metric.name], where, metrics_dir=available)
        wanted = ["run_id", "episode_id", "device_id", "category"]
        on_episodes = [c for c in by if store.has_column(EPISODES_TABLE, c) and c not in wanted]
        rows = episodes(store, where, columns=[*wanted, *on_episodes])
        rows = rows.join(terms, on=["run_id", "episode_id"], how="inner")
    on_runs = [c for c in by if c not in rows.columns]
    if on_runs:
        rows = rows.join(run_columns(store, ["run_id", *on_runs]), on="run_id", how="left")
    return rows


def _ordered_type(kind: pl.DataType) -> bool:
    """Whether polars' `<` and its sort order values of `kind` alike (text by its bytes)."""
    return kind == pl.String or kind == pl.Boolean or kind.is_integer()


def _ascending(frame: pl.DataFrame, keys: Sequence[str]) -> bool:
    """Whether each row's `keys` come at or before the next row's, as a sort by `keys` with
    nulls last orders them (lexicographically: a key decides where those before it tie)."""
    before, tied = pl.lit(False), pl.lit(True)
    for key in keys:
        this, after = pl.col(key), pl.col(key).shift(-1)
        less = ((this < after) | (this.is_not_null() & after.is_null())).fill_null(False)
        before, tied = before | (tied & less), tied & this.eq_missing(after)
    return bool(frame.select((before | tied).head(frame.height - 1).all()).item())


def sorted_by(frame: pl.DataFrame, keys: Sequence[str]) -> pl.DataFrame:
    """`frame` sorted by `keys`, nulls last; as it is when its rows are in that order
    already (the terms kept per episode come sorted by run and episode, and a grouping by
    run columns keeps that order: sorting 9.3 million rows again took 2 s at 100x). The
    keys end with a unique one (the episode within its run), so the order is one."""
    checked = frame.height > 1 and all(_ordered_type(frame.schema[k]) for k in keys)
    return frame if checked and _ascending(frame, keys) else frame.sort(keys, nulls_last=True)


def _groups(
    ordered: pl.DataFrame, by: Sequence[str], terms: Sequence[str], code: str
) -> Iterator[tuple[tuple, np.ndarray, np.ndarray]]:
    """(group values, its (n x 2) terms as floats, its cluster codes) of each group of `by`
    in a frame sorted by it: one conversion to numpy of the whole frame, sliced at the rows
    where a group value changes (a null equal to a null), instead of a frame per group
    (900 groups of 10,000 episodes at 100x: 3 s)."""
    if ordered.height == 0:
        return
    values = float_matrix(ordered, terms)
    codes = ordered[code].to_numpy().astype(np.int64)
    changed = pl.any_horizontal(
        [pl.col(c).ne_missing(pl.col(c).shift(1)).fill_null(True) for c in by] or [pl.lit(False)]
    )
    starts = np.flatnonzero(ordered.select(changed.alias("start"))["start"].to_numpy())
    starts = np.union1d([0], starts)
    ends = [*starts[1:], ordered.height]
    group_keys = ordered.select(by)[starts].rows() if by else [()]
    for key, start, end in zip(group_keys, starts, ends, strict=True):
        yield key, values[start:end], codes[start:end]


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
    frame = _grouped_terms(store, chosen, by, where, available)
    num, den = f"{chosen.name}:num", f"{chosen.name}:den"
    code = cluster_code_column(CLUSTER_COLUMNS[cluster], by)  # each group's cluster codes
    ordered = sorted_by(frame, [*by, "run_id", "episode_id"]).with_columns(code)
    keys, sums, naive = [], [], []
    for key, values, codes in _groups(ordered, by, [num, den], code.meta.output_name()):
        keys.append(key)
        sums.append(cluster_sums(values, codes, int(codes.max()) + 1))
        naive.append(values)
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
