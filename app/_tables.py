"""Tables as the pages show them: group labels, number formats, metric and cost headers, the
best value of each metric marked, the columns of the drill-down tables and the row a person
selected; and the short texts that go with them."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import pandas as pd
import polars as pl
import streamlit as st

from app._data import metric_set
from vge_analytics import dashboard as dash
from vge_analytics.reports import MISSING


def labelled(df: pl.DataFrame, by: Sequence[str]) -> pl.DataFrame:
    """`df` with a `group` label column first (the run id when grouped by run; the run_id
    column itself is then dropped as a duplicate)."""
    out = df.with_columns(dash.group_labels(df, by))
    drop = {"group", "run_id"} if "run_id" in by and "model" in by and len(by) == 2 else {"group"}
    return out.select("group", *[c for c in df.columns if c not in drop])


# ------------------------------------------------------------------------------ tables


def number_config(df: pl.DataFrame, digits: int = 2) -> dict[str, Any]:
    """Column formats showing every float column of `df` with `digits` decimals."""
    return {
        c: st.column_config.NumberColumn(format=f"%.{digits}f")
        for c, t in df.schema.items()
        if t in (pl.Float64, pl.Float32)
    }


def table_height(df: pl.DataFrame) -> int:
    """Pixel height showing every row of a small table without a scrollbar."""
    return 38 + 35 * df.height


def number_table(
    df: pl.DataFrame, *, digits: int = 2, key: str | None = None, every_row: bool = False
) -> None:
    """A table of numbers with `digits` decimals; `every_row` shows all rows, no scrollbar."""
    st.dataframe(
        df,
        hide_index=True,
        column_config=number_config(df, digits),
        height=table_height(df) if every_row else "auto",
        key=key,
        placeholder=MISSING,
    )


def metric_column_config(names: Sequence[str]) -> dict[str, Any]:
    """Column formats for metric columns: 2 decimals, header with the paper's arrow (and
    `dash.ORIGIN_MARKS` for a metric the metrics folder overrides or adds), the definition on hover."""
    metrics = metric_set()
    headers = dash.metric_headers(names, metrics)
    return {
        name: st.column_config.NumberColumn(
            headers[name], format="%.2f", help=dash.metric_help(name, metrics)
        )
        for name in names
    }


def cost_column_config() -> dict[str, Any]:
    """Column formats for the leaderboard's cost columns: dollars, 4 decimals, wide enough
    for their header."""
    return {
        name: st.column_config.NumberColumn(header, format="$%.4f", width=dash.text_width(header))
        for name, header in dash.COST_COLUMNS.items()
    }


def group_column_config(df: pl.DataFrame) -> dict[str, Any]:
    """The group label column as wide as its longest label (the grid sizes a column by its
    first rows only, cutting a longer label further down: `random-cut (incomplete)`), and
    pinned, so a row keeps its name while the table scrolls sideways."""
    labels = df["group"].cast(pl.String).to_list() if "group" in df.columns else []
    return {"group": st.column_config.TextColumn(width=dash.text_width("group", *labels), pinned=True)}


def best_styler(df: pl.DataFrame, metric_names: Sequence[str]) -> Any:
    """A pandas Styler of `df` with each metric's best value(s) in bold on green."""
    best = dash.best_rows(df, metric_names, metric_set())
    pdf = df.to_pandas()

    def style(column: pd.Series) -> list[str]:
        rows = set(best.get(str(column.name), []))
        return [
            "font-weight: bold; background-color: rgba(38, 191, 77, 0.25)" if i in rows else ""
            for i in range(len(column))
        ]

    present = [m for m in metric_names if m in pdf.columns]
    return pdf.style.apply(style, subset=present).format(precision=2, na_rep=MISSING, subset=present)


def all_metrics() -> tuple[str, ...]:
    """Every metric the pages show: the built-ins, then those the metrics folder adds."""
    return metric_set().names


STEP_COLUMNS: tuple[str, ...] = (
    "run_id",
    "episode_id",
    "step",
    "goal_index",
    "view_before",
    "action_raw",
    "feedback_kind",
    "error_type",
    "error_detail",
    "state_before",
    "state_after",
)
"""Columns of the drill-down step tables (what a person scans to pick a step)."""
MAX_ROWS = 500
"""Rows a drill-down table shows (the caption gives the full count)."""


def selected_row(df: pl.DataFrame, selection: Any) -> dict | None:
    """The row a single-row dataframe selection points at, or None."""
    try:
        rows = selection.selection.rows
    except AttributeError:
        return None
    if not rows or rows[0] >= df.height:
        return None
    return df.row(rows[0], named=True)


EPISODE_COLUMNS: tuple[str, ...] = (
    "episode_id",
    "device_id",
    "category",
    "n_goals",
    "goals_completed",
    "success",
    "termination",
    "L_act",
    "L_opt",
    "spl",
    "state_f1",
)


def view_label(views: pl.DataFrame, view: str) -> str:
    n = views.filter(views["view"] == view)["interactions"].sum()
    return f"{view}: {n} clicks"


def click_summary(points: pl.DataFrame) -> str:
    counts = dash.click_counts(points)
    total = sum(counts.values())
    parts = ", ".join(f"{n} {outcome}" for outcome, n in counts.items())
    return (
        f"{total} clicks ({parts}). Green boxes: components that were the nearest target of a "
        "click shown; grey: the view's other components."
    )


__all__ = [
    "EPISODE_COLUMNS",
    "MAX_ROWS",
    "STEP_COLUMNS",
    "all_metrics",
    "best_styler",
    "click_summary",
    "cost_column_config",
    "labelled",
    "metric_column_config",
    "number_config",
    "number_table",
    "selected_row",
    "table_height",
    "view_label",
]
