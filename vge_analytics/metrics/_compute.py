"""PROTOCOL §6 metrics in DuckDB: the registry's SQL, grouped by any column, at query time.

Which metrics, and whether they can be grouped and filtered as asked, is said here; the
statement computing them (every metric's numerator and denominator per grain, joined on the
group keys, each metric `scale * numerator / nullif(denominator, 0)`) is composed whole by the
store (`store.ratio_query`) and run through its guarded door (`store.run_query`).
"""

from __future__ import annotations

from collections.abc import Sequence

import polars as pl

from replay.io import EPISODES_TABLE, GOALS_TABLE, RUNS_TABLE, STEPS_TABLE

from .._errors import UnknownColumnError
from ..store import (
    Filters,
    GroupBy,
    Store,
    cached_store,
    open_store,
    parse_by,
    ratio_query,
    run_query,
)
from ._registry import Metric
from ._set import MetricSet, MetricsSource, metric_set

MetricNames = str | Sequence[str] | None


def _check_grains(
    store: Store, columns: Sequence[str], metrics: list[Metric], available: MetricSet
) -> None:
    """A steps- or goals-only column can group only the metrics computed from that table."""
    for col in columns:
        if store.has_column(EPISODES_TABLE, col) or store.has_column(RUNS_TABLE, col):
            continue
        tables = [t for t in (STEPS_TABLE, GOALS_TABLE) if store.has_column(t, col)]
        if not tables:
            continue  # unknown everywhere: the store's column check says so
        blocked = [m.name for m in metrics if m.grain not in tables]
        if blocked:
            usable = [m.name for m in available if m.grain in tables]
            raise UnknownColumnError(
                f"column {col!r} belongs to {' and '.join(tables)}, so it can only group or "
                f"filter metrics computed from there ({', '.join(usable)}), not "
                f"{', '.join(blocked)}; pass metrics=[...] (--metrics) accordingly"
            )


def _computed(
    out,
    by: Sequence[str],
    names: MetricNames,
    where: Filters,
    metrics_dir: MetricsSource,
    *,
    terms: bool = False,
    cache: bool = False,
) -> tuple[pl.DataFrame, list[Metric]]:
    """The metrics `names` of the set `metrics_dir` per group of `by` (or their terms), and
    the metrics chosen: checked here, composed and run by the store; with `cache`, from the
    episodes' terms kept beside OUT where they can answer (`store.cached_store`)."""
    store = open_store(out)
    available = metric_set(metrics_dir)
    chosen = available.resolve(names)
    clash = [m.name for m in chosen if m.name in by]
    if clash:
        raise UnknownColumnError(
            f"metric {clash[0]!r} has the name of a grouping column; group by other columns"
        )
    _check_grains(store, [*by, *(where or {})], chosen, available)
    cached: dict[str, str] = {}
    sources = available.files_of(chosen)
    if cache:
        store, cached = cached_store(
            store, chosen, list(available), by, where, files_of=available.files_of
        )
    sql, params = ratio_query(store, by, chosen, where, terms=terms, cached=cached)
    return run_query(store, sql, params, sources=sources), chosen


def metrics(
    out,
    by: GroupBy = None,
    metrics: MetricNames = None,
    where: Filters = None,
    *,
    metrics_dir: MetricsSource = None,
    cache: bool = True,
) -> pl.DataFrame:
    """PROTOCOL §6 metrics per group, as a polars DataFrame.

    - `out`: a replay output directory (or an open `Store`).
    - `by`: grouping columns (list or comma-separated string) of runs or episodes (model,
      category, device_id, n_goals, agent_kind, termination, `meta_<facet>`...); step columns
      (e.g. `action_type`) only with metrics computed from steps. Default: run_id, model.
      An empty list gives one row over everything.
    - `metrics`: names as PROTOCOL §6 writes them (default: all twelve, in that order, then
      the metrics a metrics folder adds).
    - `where`: `{column: value or list of values}` filters (bound, never formatted).
    - `metrics_dir`: a folder of metric files (overriding built-ins, adding metrics), or a
      loaded `MetricSet`; default `$VGE_METRICS_DIR`, else the built-ins alone.
    - `cache`: read the metrics' per-episode terms kept in `OUT/.metric-cache/` (computed and
      written there on first use; docs/METRICS.md, The metric cache); False reads the tables
      alone. The values are the same either way.

    Columns: the group columns, then one Float64 column per metric (null for an empty group).
    """
    df, chosen = _computed(out, parse_by(by), metrics, where, metrics_dir, cache=cache)
    return df.with_columns(pl.col(m.name).cast(pl.Float64) for m in chosen)


def episode_terms(
    out,
    metrics: MetricNames = None,
    where: Filters = None,
    *,
    metrics_dir: MetricsSource = None,
) -> pl.DataFrame:
    """Numerator and denominator of each metric per episode (run_id, episode_id).

    Adding the terms of any set of episodes and taking `scale * num / den` gives that set's
    pooled metric: this is what the paired bootstrap of `compare` resamples.
    """
    return _computed(out, ("run_id", "episode_id"), metrics, where, metrics_dir, terms=True)[0]


def metric_table(metrics_dir: MetricsSource = None) -> pl.DataFrame:
    """The metrics as a table: metric, title, direction, unit, level, grain, version,
    definition, null_rule, source (the file defining it) and origin (`built-in`,
    `override` or `added`)."""
    available = metric_set(metrics_dir)
    rows = [
        {
            "metric": m.name,
            "title": m.title,
            "direction": m.direction,
            "unit": m.unit,
            "level": m.level,
            "grain": m.grain,
            "version": m.version,
            "definition": m.definition,
            "null_rule": m.null_rule,
            "source": m.source,
            "origin": available.origin(m.name),
        }
        for m in available
    ]
    return pl.DataFrame(rows)


__all__ = ["episode_terms", "metric_table", "metrics"]
