"""What a metrics folder does to the leaderboard (`vge rescore`).

Two metric sets are compared: *after*, the built-ins with a folder's files (`metrics_dir`),
and *before*, the built-ins alone or with another folder (`against`). A metric is reported
when the folder changes it (`changed`: its grain, unit, direction or SQL differ; a file that
only rewords the title, the definition or the version changes no value and is not reported),
adds it (`added`: before is null), or, against another folder, no longer has it
(`removed`: after is null).

For each such metric and each group of `by` (default: per run), the value before and after,
the difference after - before, and the rank of the group before and after among all groups
(`_ranking`: rank 1 = best in the metric's direction, ties share a rank, a null value has no
rank). Per metric: Kendall's tau-b between the two rankings, over the groups ranked in both
(null for an added or removed metric, or fewer than two such groups), and the groups whose
rank moved (a group that gains or loses its rank counts as moved).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import polars as pl

from .._errors import ConfigError, UnknownMetricError
from ..metrics import Metric, MetricSet, MetricsSource, default_folder, metric_set, same_definition
from ..metrics import metrics as compute_metrics
from ..store import Filters, GroupBy, open_store, parse_by
from ._defaults import DEFAULT_RESCORE_BY
from ._format import MISSING
from ._ranking import competition_ranks, kendall_tau_b

CHANGES: tuple[str, ...] = ("changed", "added", "removed")


@dataclass(frozen=True)
class MetricChange:
    """One metric the folder changes: its definitions before and after (None when absent)."""

    name: str
    change: str
    """`changed`, `added` or `removed`."""
    before: Metric | None
    after: Metric | None


@dataclass(frozen=True)
class Rescore:
    """Result of `rescore`."""

    by: tuple[str, ...]
    rows: pl.DataFrame
    """metric, the group columns, before, after, delta (after - before), rank_before,
    rank_after; per metric, by rank after (then before, then the groups)."""
    summary: pl.DataFrame
    """metric, change, source (the file defining it after, or before when removed), groups
    (ranked before and after), kendall_tau_b, moved (labels of the groups whose rank moved,
    `<group> <before>→<after>`)."""
    changes: tuple[MetricChange, ...]

    def tables(self) -> dict[str, pl.DataFrame]:
        """The two tables shown to people: `changes` (the rows with how each rank moved,
        `move`) and `rankings` (the summary, moved groups on one line)."""
        return {
            "changes": self.rows.with_columns(rank_moves(self.rows)),
            "rankings": self.summary.with_columns(pl.col("moved").list.join(", ")),
        }


def rank_moves(rows: pl.DataFrame) -> pl.Series:
    """How each group's rank moved, for people: `▲ 2` (up two places), `▼ 1`, `=`, `new`
    (ranked after only), `gone` (ranked before only), `–` (ranked in neither)."""
    labels = []
    for before, after in rows.select("rank_before", "rank_after").iter_rows():
        if before is None and after is None:
            labels.append(MISSING)
        elif before is None:
            labels.append("new")
        elif after is None:
            labels.append("gone")
        elif after < before:
            labels.append(f"\u25b2 {before - after}")
        elif after > before:
            labels.append(f"\u25bc {after - before}")
        else:
            labels.append("=")
    return pl.Series("move", labels, dtype=pl.String)


def metric_changes(after: MetricSet, before: MetricSet) -> list[MetricChange]:
    """The metrics `after` changes, adds or removes relative to `before`, in `after`'s
    order (removed ones last, in `before`'s order)."""
    found: list[MetricChange] = []
    for m in after:
        if m.name not in before:
            found.append(MetricChange(m.name, "added", None, m))
        elif not same_definition(before.get(m.name), m):
            found.append(MetricChange(m.name, "changed", before.get(m.name), m))
    for m in before:
        if m.name not in after:
            found.append(MetricChange(m.name, "removed", m, None))
    return found


def group_label(row: dict, by: Sequence[str]) -> str:
    """The group values of a row joined by ` · ` (null as ∅); with run_id among the groups,
    model is left out (a run has one model)."""
    shown = [c for c in by if not (c == "model" and "run_id" in by)]
    return " · ".join("∅" if row[c] is None else str(row[c]) for c in shown) or "all"


def _values(
    out, by: tuple[str, ...], where: Filters, names: list[str], available: MetricSet
) -> pl.DataFrame:
    if not names:
        return pl.DataFrame()
    return compute_metrics(out, by=by, metrics=names, where=where, metrics_dir=available)


def _keys(before: pl.DataFrame, after: pl.DataFrame, by: tuple[str, ...]) -> pl.DataFrame:
    frames = [f.select(by) for f in (before, after) if f.width]
    keys = pl.concat(frames).unique() if len(frames) > 1 else frames[0]
    return keys.sort(list(by), nulls_last=True)


def _column(frame: pl.DataFrame, keys: pl.DataFrame, by: tuple[str, ...], name: str) -> list:
    if not frame.width or name not in frame.columns:
        return [None] * keys.height
    joined = keys.join(
        frame.select(*by, pl.col(name).alias("__v")),
        on=list(by),
        how="left",
        nulls_equal=True,
        maintain_order="left",
    )
    return joined["__v"].to_list()


def _chosen(changes: list[MetricChange], names: str | Sequence[str] | None) -> list[MetricChange]:
    """The changes of the metrics named (all when None); a name the folder does not change
    is an error that lists those it does."""
    if names is None:
        return changes
    if isinstance(names, str):
        names = [n.strip() for n in names.split(",") if n.strip()]
    by_name = {c.name: c for c in changes}
    unknown = [n for n in names if n not in by_name]
    if unknown or not names:
        changed = ", ".join(by_name) or "none"
        raise UnknownMetricError(
            f"the metrics folder does not change {', '.join(map(repr, unknown)) or 'them'}; "
            f"the metrics it changes or adds: {changed}"
        )
    return [by_name[n] for n in dict.fromkeys(names)]


_ROW_SCHEMA = {
    "before": pl.Float64,
    "after": pl.Float64,
    "delta": pl.Float64,
    "rank_before": pl.Int64,
    "rank_after": pl.Int64,
}
_SUMMARY_SCHEMA = {
    "metric": pl.String,
    "change": pl.String,
    "source": pl.String,
    "groups": pl.Int64,
    "kendall_tau_b": pl.Float64,
    "moved": pl.List(pl.String),
}


def _ranked(
    change: MetricChange,
    keys: pl.DataFrame,
    by_cols: Sequence[str],
    before: pl.DataFrame,
    after: pl.DataFrame,
) -> pl.DataFrame:
    """A changed metric's rows: each group's value and rank before and after, the delta,
    sorted by the rank after."""
    b = _column(before, keys, by_cols, change.name)
    a = _column(after, keys, by_cols, change.name)
    rb = competition_ranks(b, change.before.higher_is_better) if change.before else b
    ra = competition_ranks(a, change.after.higher_is_better) if change.after else a
    part = keys.with_columns(
        pl.Series("before", b, dtype=pl.Float64),
        pl.Series("after", a, dtype=pl.Float64),
        pl.Series("rank_before", rb, dtype=pl.Int64),
        pl.Series("rank_after", ra, dtype=pl.Int64),
    ).with_columns(delta=pl.col("after") - pl.col("before"))
    return part.select(pl.lit(change.name).alias("metric"), *by_cols, *_ROW_SCHEMA).sort(
        ["rank_after", "rank_before", *by_cols], nulls_last=True, maintain_order=True
    )


def _ranking_summary(change: MetricChange, part: pl.DataFrame, by_cols: Sequence[str]) -> dict:
    """A changed metric in one row: Kendall's tau-b between its rankings and the groups whose
    rank moved."""
    both = part.filter(pl.col("rank_before").is_not_null() & pl.col("rank_after").is_not_null())
    tau = (
        kendall_tau_b(both["rank_before"].to_list(), both["rank_after"].to_list())
        if change.change == "changed"
        else None
    )
    moved = []
    if change.change == "changed":
        for row in part.iter_rows(named=True):
            if row["rank_before"] != row["rank_after"]:
                shown = [
                    MISSING if r is None else str(r) for r in (row["rank_before"], row["rank_after"])
                ]
                moved.append(f"{group_label(row, by_cols)} {shown[0]}→{shown[1]}")
    source = (change.after or change.before).source  # type: ignore[union-attr]
    return {
        "metric": change.name,
        "change": change.change,
        "source": source,
        "groups": both.height,
        "kendall_tau_b": tau,
        "moved": moved,
    }


def rescore(
    out,
    metrics_dir: MetricsSource = None,
    *,
    against: MetricsSource = None,
    by: GroupBy = DEFAULT_RESCORE_BY,
    where: Filters = None,
    metrics: str | Sequence[str] | None = None,
) -> Rescore:
    """What the metrics of `metrics_dir` (default `$VGE_METRICS_DIR`) change, per group of
    `by` (default per run), relative to the built-ins, or to the metrics of `against`
    (another folder, or a `MetricSet`). `metrics`: only these of the changed metrics
    (default: all of them). See the module docstring."""
    store = open_store(out)
    if metrics_dir is None and default_folder() is None:
        raise ConfigError("rescore needs a metrics folder: --metrics-dir DIR (or $VGE_METRICS_DIR)")
    after_set = metric_set(metrics_dir)
    before_set = MetricSet.builtin() if against is None else metric_set(against)
    by_cols = parse_by(by)
    if not by_cols:
        raise ConfigError("rescore ranks groups: --by needs at least one column (e.g. run_id)")
    changes = _chosen(metric_changes(after_set, before_set), metrics)
    before = _values(
        store, by_cols, where, [c.name for c in changes if c.before is not None], before_set
    )
    after = _values(
        store, by_cols, where, [c.name for c in changes if c.after is not None], after_set
    )
    parts: list[pl.DataFrame] = []
    summary: list[dict] = []
    keys = _keys(before, after, by_cols) if changes else pl.DataFrame()
    for change in changes:
        part = _ranked(change, keys, by_cols, before, after)
        parts.append(part)
        summary.append(_ranking_summary(change, part, by_cols))
    if parts:
        rows = pl.concat(parts, how="vertical_relaxed")
    else:  # nothing changed: the columns, no row
        rows = pl.DataFrame(schema={"metric": pl.String, **dict.fromkeys(by_cols, pl.String)})
        rows = rows.with_columns(pl.lit(None, dtype=t).alias(c) for c, t in _ROW_SCHEMA.items())
    return Rescore(
        by=by_cols,
        rows=rows,
        summary=pl.DataFrame(summary, schema=_SUMMARY_SCHEMA),
        changes=tuple(changes),
    )


__all__ = [
    "CHANGES",
    "MetricChange",
    "Rescore",
    "group_label",
    "metric_changes",
    "rank_moves",
    "rescore",
]
