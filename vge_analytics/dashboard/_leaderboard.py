"""The Leaderboard page: metric tables, their headers, notes and best values."""


from __future__ import annotations

import math
from collections.abc import Sequence

import polars as pl

from ..metrics import Metric, MetricSet


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


ORIGIN_MARKS: dict[str, str] = {"built-in": "", "override": " ✎", "added": " ＋"}
"""What a leaderboard header carries after its arrow: a metric a metrics folder overrides
(✎) or adds (＋)."""


def metric_headers(metric_names: Sequence[str], metrics: MetricSet | None = None) -> dict[str, str]:
    """{metric: header with the paper's arrow and its origin mark}, e.g. `SR ↑`, `VSPS ↓`,
    `SR ↑ ✎` (overridden by a metrics folder), `SR-multi ↑ ＋` (added by one)."""
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
        parts.append(f"✎ overridden: {', '.join(overridden)}")
    if added:
        parts.append(f"＋ added: {', '.join(added)}")
    what = "; ".join(parts) if parts else "no metric changed"
    return f"Metrics of `{metrics.folder}`: {what}. Hover a header for its definition."


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
