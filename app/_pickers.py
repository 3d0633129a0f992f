"""The widgets that choose what a page shows: the grouping, the row of run, category and
grouping pickers, the step sliders, the SQL examples; and keeping a picker's value valid."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import polars as pl
import streamlit as st

from app import _data as data
from app._sidebar import where
from replay.io import EPISODES_TABLE
from vge_analytics import dashboard as dash

GROUPINGS: dict[str, tuple[str, ...]] = {
    "run": ("run_id", "model"),
    "model": ("model",),
    "agent kind": ("agent_kind",),
    "category": ("category",),
    "goal count": ("n_goals",),
}


def group_by_picker(key: str, *, label: str = "Group by") -> tuple[str, ...]:
    """A selectbox of groupings (run, model, agent kind, category, goal count, each facet)."""
    options = dict(GROUPINGS)
    for column in data.facets():
        options[f"model × {column.removeprefix('meta_')}"] = ("model", column)
    choice = st.selectbox(label, list(options), key=key)
    return options[choice]


class Selection(NamedTuple):
    """What a page's filter row chose: runs, categories, the grouping and the filters."""

    runs: list[str]
    categories: list[str]
    by: tuple[str, ...]
    where: dict[str, list]


def filter_row(key: str) -> Selection:
    """The row of pickers shared by the analysis pages: runs, category, group by."""
    c1, c2, c3 = st.columns([3, 2, 2])
    runs = c1.multiselect("Runs", data.runs()["run_id"].to_list(), placeholder="all runs")
    categories = c2.multiselect(
        "Category", data.column_values(EPISODES_TABLE, "category"), placeholder="all"
    )
    with c3:
        by = group_by_picker(f"{key}_by")
    return Selection(runs, categories, by, where(run_id=runs, category=categories))


def charts_wanted(groups: int, bars: int, key: str) -> bool:
    """Whether to draw a page's charts of `groups` groups (`bars` bars in all): always up to
    `dash.CHART_AUTO_GROUPS` groups; above, when the person turns on the switch shown
    where they go (a browser takes seconds to draw thousands of bars)."""
    if groups <= dash.CHART_AUTO_GROUPS:
        return True
    label = f"Draw the charts: {groups:,} groups, {bars:,} bars (a browser takes seconds)"
    return st.toggle(label, key=key)


def step_slider(steps: pl.DataFrame) -> int:
    """The step picker (a slider over the episode's steps); returns the chosen position."""
    last = steps.height - 1
    current = st.session_state.get("viewer_step", 0)
    if not isinstance(current, int) or not 0 <= current <= last:
        st.session_state["viewer_step"] = 0
    if last == 0:
        st.session_state["viewer_step"] = 0
        st.caption("One step.")
        return 0
    return int(st.slider("Step", 0, last, key="viewer_step"))


def _go_to_step(step: int) -> None:
    st.session_state["sbs_step"] = step


def side_step_slider(n_steps: int, marks: dict[int, list[str]]) -> int:
    """The shared step picker of the Side by side page, over `n_steps` (the longer log),
    each step named with its marks (first difference, first errors), and a button per
    marked step that jumps there; returns the chosen step."""
    current = st.session_state.get("sbs_step", 0)
    if not isinstance(current, int) or not 0 <= current < n_steps:
        st.session_state["sbs_step"] = 0
    buttons = st.columns(max(len(marks), 1))
    for column, (step, texts) in zip(buttons, sorted(marks.items()), strict=False):
        column.button(
            f"Step {step}: {', '.join(texts)}",
            key=f"sbs_jump_{step}",
            on_click=_go_to_step,
            args=(step,),
            disabled=step >= n_steps,
        )
    if n_steps <= 1:
        st.session_state["sbs_step"] = 0
        st.caption("One step.")
        return 0
    return int(
        st.select_slider(
            "Step (both runs)",
            options=list(range(n_steps)),
            format_func=lambda k: dash.step_label(k, marks),
            key="sbs_step",
        )
    )


LAMBDA_CHOICES: tuple[float, ...] = (1, 1.5, 2, 2.5, 3, 4, 5, 6, 8, 10)
"""λ values the budgets page offers."""


def load_example() -> None:
    """Callback of the examples picker: put the chosen query in the query box."""
    name = st.session_state.get("sql_example")
    if name in dash.EXAMPLE_QUERIES:
        st.session_state["sql_query"] = dash.EXAMPLE_QUERIES[name]


def init_state(key: str, value: Any) -> None:
    """Give a widget its first value through the session state (before it is drawn)."""
    if key not in st.session_state:
        st.session_state[key] = value


def keep_choice(key: str, options: Sequence[Any]) -> None:
    """Forget a picker's remembered value when it is no longer one of its options."""
    if key in st.session_state and st.session_state[key] not in options:
        del st.session_state[key]


__all__ = [
    "GROUPINGS",
    "LAMBDA_CHOICES",
    "Selection",
    "charts_wanted",
    "filter_row",
    "group_by_picker",
    "init_state",
    "keep_choice",
    "load_example",
    "side_step_slider",
    "step_slider",
]
