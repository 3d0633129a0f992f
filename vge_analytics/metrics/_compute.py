"""PROTOCOL §6 metrics in DuckDB: the registry's SQL, grouped by any column, at query time.

One statement per call: for each grain the requested metrics need (episodes, steps, goals),
one aggregate over that table (joined to episodes/runs only when a grouping or filter column
lives there) computing every metric's numerator and denominator; the aggregates are joined on
the group keys and each metric is `scale * numerator / nullif(denominator, 0)`, so an empty
group gives null and never a division error. Groups come out sorted by the group columns.
"""

from __future__ import annotations

from collections.abc import Sequence

import polars as pl

from replay.io import EPISODES_TABLE, GOALS_TABLE, GRAINS, RUNS_TABLE, STEPS_TABLE

from .._errors import UnknownColumnError
from ..store import (
    Filters,
    GroupBy,
    Store,
    check_columns,
    grouped_aggregate,
    null_safe_join,
    open_store,
    order_by,
    parse_by,
    quote_ident,
    run_keys_scope,
    run_query,
)
from ._registry import Metric
from ._set import MetricSet, MetricsSource, metric_set

MetricNames = str | Sequence[str] | None


def _term(metric: Metric, part: str) -> str:
    return quote_ident(f"{metric.name}:{part}")


def _grain_query(store: Store, grain: str, metrics: list[Metric], by, where) -> tuple[str, list]:
    # Each expression on lines of its own, as `_metric_check` binds it: a trailing `--`
    # comment in a metric file ends with its line.
    terms = []
    for m in metrics:
        terms.append((f"coalesce(\n{m.numerator}\n, 0)", f"{m.name}:num"))
        terms.append((f"coalesce(\n{m.denominator}\n, 0)", f"{m.name}:den"))
    return grouped_aggregate(store, grain, by, where, terms)


def _check_grains(
    store: Store, columns: Sequence[str], metrics: list[Metric], available: MetricSet
) -> None:
    """A steps- or goals-only column can group only the metrics computed from that table."""
    for col in columns:
        if store.has_column(EPISODES_TABLE, col) or store.has_column(RUNS_TABLE, col):
            continue
        tables = [t for t in (STEPS_TABLE, GOALS_TABLE) if store.has_column(t, col)]
        if not tables:
            continue  # unknown everywhere: check_columns says so
        blocked = [m.name for m in metrics if m.grain not in tables]
        if blocked:
            usable = [m.name for m in available if m.grain in tables]
            raise UnknownColumnError(
                f"column {col!r} belongs to {' and '.join(tables)}, so it can only group or "
                f"filter metrics computed from there ({', '.join(usable)}), not "
                f"{', '.join(blocked)}; pass metrics=[...] (--metrics) accordingly"
            )


def compose(
    store: Store,
    by: Sequence[str],
    metrics: list[Metric],
    where: Filters = None,
    *,
    terms: bool = False,
    available: MetricSet | None = None,
) -> tuple[str, list]:
    """The SQL text and bound parameters computing `metrics` per group of `by`.

    With `terms=True` the result holds each metric's numerator and denominator
    (`"<name>:num"`, `"<name>:den"`) instead of its value. `available`: the set `metrics`
    come from (named in messages; default the built-ins).
    """
    grains = [g for g in GRAINS if any(m.grain == g for m in metrics)]
    clash = [m.name for m in metrics if m.name in by]
    if clash:
        raise UnknownColumnError(
            f"metric {clash[0]!r} has the name of a grouping column; group by other columns"
        )
    _check_grains(store, [*by, *(where or {})], metrics, available or MetricSet.builtin())
    check_columns(store, [*by, *(where or {})], grains, "grouping/filter")
    ctes: list[str] = []
    params: list[object] = []
    for grain in grains:
        sql, p = _grain_query(store, grain, [m for m in metrics if m.grain == grain], by, where)
        ctes.append(f"agg_{grain} AS ({sql})")
        params.extend(p)

    key_names = list(by)
    keys_cols = ", ".join(quote_ident(n) for n in key_names)
    runs_scope = run_keys_scope(store, by, where)
    if not key_names:
        keys_sql = "SELECT 1 AS __one"
    elif runs_scope is not None:
        keys_sql = (
            f"SELECT DISTINCT {runs_scope.key_select} FROM {runs_scope.from_sql} "
            f"WHERE {runs_scope.where_sql}"
        )
        params.extend(runs_scope.params)
        # Groups present in the data but missing from runs (should not happen) still show.
        keys_sql += "".join(f" UNION SELECT {keys_cols} FROM agg_{g}" for g in grains)
    else:
        keys_sql = " UNION ".join(f"SELECT {keys_cols} FROM agg_{g}" for g in grains)
    ctes.append(f"keys AS ({keys_sql})")

    select = [f"k.{quote_ident(n)}" for n in key_names]
    for m in metrics:
        src = f"agg_{m.grain}"
        num, den = f"{src}.{_term(m, 'num')}", f"{src}.{_term(m, 'den')}"
        if terms:
            select.append(f"coalesce({num}, 0) AS {_term(m, 'num')}")
            select.append(f"coalesce({den}, 0) AS {_term(m, 'den')}")
        else:
            select.append(f"CAST(? AS DOUBLE) * {num} / nullif({den}, 0) AS {quote_ident(m.name)}")
    joins = "".join(
        f" LEFT JOIN agg_{g} ON {null_safe_join('k', f'agg_{g}', key_names)}" for g in grains
    )
    sql = (
        "WITH "
        + ", ".join(ctes)
        + f" SELECT {', '.join(select)} FROM keys AS k{joins}"
        + order_by(key_names, "k")
    )
    if not terms:
        params.extend(m.scale for m in metrics)
    return sql, params


def metrics(
    out,
    by: GroupBy = None,
    metrics: MetricNames = None,
    where: Filters = None,
    *,
    metrics_dir: MetricsSource = None,
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

    Columns: the group columns, then one Float64 column per metric (null for an empty group).
    """
    store = open_store(out)
    available = metric_set(metrics_dir)
    chosen = available.resolve(metrics)
    by_cols = parse_by(by)
    sql, params = compose(store, by_cols, chosen, where, available=available)
    df = run_query(store, sql, params)
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
    store = open_store(out)
    available = metric_set(metrics_dir)
    chosen = available.resolve(metrics)
    sql, params = compose(
        store, ("run_id", "episode_id"), chosen, where, terms=True, available=available
    )
    return run_query(store, sql, params)


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


__all__ = ["compose", "episode_terms", "metric_table", "metrics", "run_query"]
