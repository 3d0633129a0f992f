"""The sidebar every page over OUT shares: which OUT is open, its counts, the metrics folder,
and the run-facet filters every page applies (`where`)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import polars as pl
import streamlit as st

import vge_analytics as va
from app import _data as data
from app._data import metric_set, out_dir
from app._lifecycle import show_error, stop
from vge_analytics import dashboard as dash
from vge_analytics.store import describe_filters


def sidebar() -> bool:
    """The OUT indicator and the run-facet filters; False (after saying why) if OUT is unusable."""
    try:
        out = out_dir()
        summary = data.out_summary()
        facets = data.facets()
    except va.AnalyticsError as exc:
        st.sidebar.error("No usable replay output")
        show_error(exc)
        return False
    try:
        metrics = metric_set()
    except va.MetricFileError as exc:
        st.sidebar.error("Unusable metrics folder")
        show_error(exc)
        return False
    with st.sidebar:
        st.caption(f"**OUT** `{out}`")
        st.caption(
            f"{summary.runs} runs · {summary.episodes} episodes · {summary.steps} steps · "
            f"engine {summary.engine_version}"
            + (f" · {summary.quarantined} quarantined" if summary.quarantined else "")
        )
        if metrics.folder is not None:
            st.caption(f"**Metrics** built-in + `{metrics.folder}`")
        if facets:
            st.markdown("**Run facets** (filter every page)")
            for column, values in facets.items():
                st.multiselect(
                    column.removeprefix("meta_"),
                    values,
                    key=f"facet:{column}",
                    placeholder="all",
                    format_func=value_label,
                )
    return True


def value_label(value: Any) -> str:
    """How a facet or column value reads in a picker (null as `(none)`)."""
    return "(none)" if value is None else str(value)


def facet_filters() -> dict[str, list]:
    """{facet column: chosen values} from the sidebar (empty choice = no filter)."""
    chosen = {}
    for key, value in st.session_state.items():
        if isinstance(key, str) and key.startswith("facet:") and value:
            chosen[key.removeprefix("facet:")] = list(value)
    return dict(sorted(chosen.items()))


def where(**extra: Sequence[Any] | None) -> dict[str, list]:
    """The facet filters plus the page's own (`column=[values]`; empty means no filter)."""
    filters = facet_filters()
    for column, values in extra.items():
        if values:
            filters[column] = list(values)
    refuse_empty(filters)
    return filters


def refuse_empty(filters: dict[str, list]) -> None:
    """Say in one line, instead of an empty table, that the filters select no row (and
    end the page there); warn about values no row holds."""
    if not filters:
        return
    check = data.selection_check(filters)
    line = check.line(f"The selection ({describe_filters(filters)})")
    if line:
        st.warning(line, icon=":material/filter_alt_off:")
    if check.empty:
        stop()


def runs_matching_facets(runs: pl.DataFrame) -> list[str]:
    """Run ids that pass the sidebar's facet filters (the page ends with one line when
    none does)."""
    filters = facet_filters()
    refuse_empty(filters)
    return dash.runs_matching(runs, filters)


__all__ = [
    "facet_filters",
    "refuse_empty",
    "runs_matching_facets",
    "sidebar",
    "value_label",
    "where",
]
