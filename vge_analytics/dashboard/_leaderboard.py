"""The Leaderboard page: metric tables, their headers, notes and best values."""

from __future__ import annotations

import math
from collections.abc import Sequence

import polars as pl

from replay.io import EPISODES_TABLE

from ..metrics import Metric, MetricSet
from ..reports import RunCompleteness, mark_incomplete, mark_rows
from ..store import (
    Filters,
    check_columns,
    grouped_aggregate,
    open_store,
    order_by,
    run_query,
)


def group_labels(df: pl.DataFrame, by: Sequence[str]) -> pl.Series:
    """One readable label per row of a grouped result: the group values joined by ` · `.

    With run_id among the groups, model is left out (a run has one model).
    """
    cols = [c for c in by if not (c == "model" and "run_id" in by)]
    if not cols:
        return pl.Series("group", ["all"] * df.height, dtype=pl.String)
    exprs = [pl.col(c).cast(pl.String).fill_null("∅") for c in cols]
    label = exprs[0] if len(exprs) == 1 else pl.concat_str(exprs, separator=" · ")
    return df.select(label.alias("group")).to_series()


def _metric(name: str, metrics: MetricSet | None) -> Metric:
    return (metrics or MetricSet.builtin()).get(name)


def best_rows(
    df: pl.DataFrame, metric_names: Sequence[str], metrics: MetricSet | None = None
) -> dict[str, list[int]]:
    """{metric: row positions holding its best value}, by the metric's direction (the
    metrics of `metrics`, default the built-ins).

    Ties are all best; a column with no value has no best row.
    """
    best: dict[str, list[int]] = {}
    for name in metric_names:
        if name not in df.columns:
            continue
        values = df[name].to_list()
        present = [v for v in values if v is not None and not math.isnan(v)]
        if not present:
            best[name] = []
            continue
        target = max(present) if _metric(name, metrics).higher_is_better else min(present)
        best[name] = [i for i, v in enumerate(values) if v is not None and math.isclose(v, target)]
    return best


ORIGIN_MARKS: dict[str, str] = {"built-in": "", "override": " ✎", "added": " +"}
"""What a leaderboard header carries after its arrow: a metric a metrics folder overrides
(✎) or adds (+). Signs the system's fonts draw (the table is a canvas drawn with them:
Debian's DejaVu has ✎ but not the full-width ＋, which showed as an empty box)."""


def metric_headers(metric_names: Sequence[str], metrics: MetricSet | None = None) -> dict[str, str]:
    """{metric: header with the paper's arrow and its origin mark}, e.g. `SR ↑`, `VSPS ↓`,
    `SR ↑ ✎` (overridden by a metrics folder), `SR-multi ↑ +` (added by one)."""
    chosen = metrics or MetricSet.builtin()
    return {n: f"{n} {chosen.get(n).arrow}{ORIGIN_MARKS[chosen.origin(n)]}" for n in metric_names}


def metric_help(name: str, metrics: MetricSet | None = None) -> str:
    """The hover text of a metric's header: title, definition, and which file overrides or
    adds it."""
    chosen = metrics or MetricSet.builtin()
    m = chosen.get(name)
    origin = chosen.origin(name)
    text = f"{m.title}: {m.definition}"
    if origin == "override":
        text += f" (overrides the built-in {name}: {m.source}, version {m.version})"
    elif origin == "added":
        text += f" (added: {m.source}, version {m.version})"
    return text


def metrics_note(metrics: MetricSet | None) -> str | None:
    """What the pages say about a metrics folder (None without one): which metrics it
    overrides and adds, and how their headers are marked."""
    if metrics is None or metrics.folder is None:
        return None
    overridden = [m.name for m in metrics if metrics.origin(m.name) == "override"]
    added = [m.name for m in metrics if metrics.origin(m.name) == "added"]
    parts = []
    if overridden:
        parts.append(f"{ORIGIN_MARKS['override'].strip()} overridden: {', '.join(overridden)}")
    if added:
        parts.append(f"{ORIGIN_MARKS['added'].strip()} added: {', '.join(added)}")
    what = "; ".join(parts) if parts else "no metric changed"
    return f"Metrics of `{metrics.folder}`: {what}. Hover a header for its definition."


CHART_AUTO_GROUPS = 100
"""Groups a chart of groups (a bar or a stack of bars per group) is drawn for on a page
load; above, the page asks first: at 100x the full benchmark (900 runs) the Leaderboard's 14
panels of 900 bars took a browser about 4 s to draw under load, the Errors page's two
stacked charts 2 s (docs/PERFORMANCE.md)."""


def metrics_long(
    df: pl.DataFrame, metric_names: Sequence[str], metrics: MetricSet | None = None
) -> pl.DataFrame:
    """A metrics table with a `group` column to long form (group, metric, value, direction),
    for one bar chart per metric; rows without a value are dropped."""
    present = [m for m in metric_names if m in df.columns]
    long = df.unpivot(index="group", on=present, variable_name="metric", value_name="value")
    directions = {m: _metric(m, metrics).direction for m in present}
    return long.drop_nulls("value").with_columns(
        direction=pl.col("metric").replace_strict(directions, return_dtype=pl.String)
    )


# ------------------------------------------------------------------ cost and completeness

COST_COLUMNS: dict[str, str] = {
    "cost_per_episode": "$ / episode",
    "cost_per_success": "$ / success",
}
"""The leaderboard's cost columns and their headers (USD; PROTOCOL §7.3 `cost_usd`)."""

_COST_TERMS = (
    ("count(*)", "episodes"),
    ("count(*) FILTER (WHERE success)", "successes"),
    ("count(cost_usd)", "costed"),
    ("fsum(cost_usd)", "cost_usd"),  # compensated: the same total whatever the row order
)


def cost_table(out, by: Sequence[str], where: Filters = None) -> pl.DataFrame:
    """Per group of `by` (columns of runs or episodes, as the metrics): `episodes`,
    `successes`, `SR` (percent), `cost_usd` (the episodes' costs summed; null when none was
    recorded), `cost_per_episode` (over the episodes with a cost) and `cost_per_success`
    (all of it over the successes: what each success cost; null without one)."""
    store = open_store(out)
    by = list(by)
    check_columns(store, [*by, *(where or {})], [EPISODES_TABLE], "grouping/filter")
    sql, params = grouped_aggregate(store, EPISODES_TABLE, by, where, _COST_TERMS)  # a row a group
    if by:
        sql = f"SELECT * FROM ({sql}){order_by(by)}"
    df = run_query(store, sql, params)
    return df.with_columns(
        pl.col("episodes", "successes", "costed").cast(pl.Int64),
        SR=100.0 * pl.col("successes") / pl.col("episodes"),
        cost_per_episode=pl.col("cost_usd") / pl.when(pl.col("costed") > 0).then("costed"),
        cost_per_success=pl.col("cost_usd") / pl.when(pl.col("successes") > 0).then("successes"),
    ).drop("costed")


def with_costs(table: pl.DataFrame, costs: pl.DataFrame, by: Sequence[str]) -> pl.DataFrame:
    """The metrics table with the cost columns of its groups right after the group columns
    (before the metrics, so they are in sight without scrolling sideways); unchanged when no
    group has a recorded cost (simulated and human runs)."""
    if costs["cost_usd"].null_count() == costs.height:
        return table
    keys = [c for c in by if c in table.columns and c in costs.columns]
    joined = table.join(costs.select(*keys, *COST_COLUMNS), on=keys, how="left", nulls_equal=True)
    labels = [c for c in table.columns if c in by]
    rest = [c for c in table.columns if c not in by]
    return joined.select(*labels, *COST_COLUMNS, *rest)


TEXT_PX_PER_CHAR = 8
"""Pixels a character takes at most in the tables' 14 px sans-serif (lower case and digits;
a bound that keeps a label whole)."""
CELL_PADDING_PX = 24
MAX_COLUMN_PX = 480
"""The widest a column sized to its text gets (a run id of a thousand characters is cut
there, not given a column wider than the page)."""


def text_width(*texts: str) -> int:
    """Pixels a table column needs to show the longest of `texts` whole, at most
    `MAX_COLUMN_PX`."""
    longest = max((len(t) for t in texts), default=0)
    return min(MAX_COLUMN_PX, longest * TEXT_PX_PER_CHAR + CELL_PADDING_PX)


def cost_frontier(runs: pl.DataFrame) -> pl.DataFrame:
    """The cost–success plane of the runs with a cost (a `cost_table` by run): `run_id`,
    `SR`, `cost_per_episode` and `frontier`, sorted by cost then SR. A run is on the frontier
    (HAL's Pareto frontier) when no other run costs at most as much per episode and succeeds
    at least as often, one of the two strictly."""
    costed = runs.filter(pl.col("cost_per_episode").is_not_null()).sort(
        "cost_per_episode", pl.col("SR"), descending=[False, True]
    )
    points = list(zip(costed["cost_per_episode"], costed["SR"], strict=True))
    frontier = [
        not any((c2 <= c and s2 >= s) and (c2 < c or s2 > s) for c2, s2 in points)
        for c, s in points
    ]
    return costed.select("run_id", "SR", "cost_per_episode").with_columns(
        frontier=pl.Series(frontier, dtype=pl.Boolean)
    )


def incomplete_groups(table: pl.DataFrame, by: Sequence[str], runs: Sequence[str]) -> pl.DataFrame:
    """A labelled table (`group` first) with `INCOMPLETE_MARK` after the label of each run of
    `runs` (the incomplete ones), when the table is grouped by run."""
    if "run_id" not in by or not runs:
        return table
    if "run_id" in table.columns:
        return mark_incomplete(table, "group", runs)
    return mark_rows(table, "group", table["group"].is_in(list(runs)))


def incomplete_note(runs: Sequence[RunCompleteness]) -> str | None:
    """What the leaderboard says above the table of incomplete runs (None: every run is
    complete, or says nothing)."""
    shown = [r for r in runs if r.incomplete]
    if not shown:
        return None
    named = "; ".join(
        f"**{r.run_id}**"
        + (
            f" ({r.infrastructure_failures} infrastructure failure(s))"
            if r.infrastructure_failures
            else ""
        )
        for r in shown
    )
    return (
        f"Incomplete: {named}. Their run.json says `complete: false`: the metrics cover the "
        f"episodes written so far, not the run's selection; `vge run --resume` completes it."
    )


# ------------------------------------------------------------------------------ intervals


def interval_rows(intervals: pl.DataFrame, by: Sequence[str], metric: str) -> pl.DataFrame:
    """`metric_intervals` for people: group label, the metric, its 95% clustered interval,
    the clustered SE, the design effect, episodes and clusters."""
    return intervals.select(
        group_labels(intervals, by),
        pl.col("value").alias(metric),
        pl.col("ci_low").alias("CI low"),
        pl.col("ci_high").alias("CI high"),
        pl.col("se").alias("SE"),
        pl.col("deff").alias("design effect"),
        pl.col("n_episodes").alias("episodes"),
        pl.col("n_clusters").alias("clusters"),
    )
