"""Errors: the paper's error taxonomy per group, and drill-down to the steps and episodes."""

import streamlit as st

from app import _charts as charts
from app import _data as data
from app import _links as links
from app import _pickers as pickers
from app import _sidebar as sidebar
from app import _tables as tables
from vge_analytics import ERROR_LABELS, ERROR_TYPES, reports
from vge_analytics import dashboard as dash

st.title("Errors")
st.caption(
    "Share of each error type among all errors of a group (the paper's error taxonomy): grounding in "
    "blue, execution in red, navigation in green, as in the paper's error pie."
)

chosen_runs, categories, by, where = pickers.filter_row("errors")

raw = data.error_distribution(by=list(by), where=where, labels=True)
dist = tables.labelled(raw, by)
groups = reports.groups_of(raw, list(by))  # from the same result: no second scan of the steps
order = dist["group"].unique(maintain_order=True).to_list()

compare_tab, pie_tab, table_tab = st.tabs(["Compare groups", "Pie of one group", "Table"])
with compare_tab:
    if pickers.charts_wanted(len(order), dist.height + groups.height, "errors_charts"):
        st.altair_chart(charts.error_stacked(dist, order))
        st.altair_chart(charts.error_group_stacked(tables.labelled(groups, by), order))
with pie_tab:
    one = st.selectbox("Group", order, key="errors_pie_group")
    part = dist.filter(dist["group"] == one)
    if part["count"].sum() == 0:
        st.info(f"{one} made no error.")
    else:
        st.markdown(f"**{one}**: {part['count'].sum()} errors")
        st.altair_chart(charts.error_donut(part))
with table_tab:
    shares = dash.error_share_wide(dist)
    tables.number_table(shares, digits=1)

st.subheader("Drill down: steps with an error")
d1, d2 = st.columns([2, 3])
error_type = d1.selectbox(
    "Error type", ERROR_TYPES, format_func=ERROR_LABELS.get, key="errors_drill_type"
)
drill_runs = d2.multiselect(
    "Runs",
    data.runs()["run_id"].to_list(),
    default=chosen_runs,
    placeholder="all runs",
    key="errors_drill_runs",
)
steps, total = data.error_step_sample(
    error_type,
    where=sidebar.where(run_id=drill_runs, category=categories),
    columns=tables.STEP_COLUMNS,
    limit=tables.MAX_ROWS,
)
shown = "" if total <= steps.height else f" (the first {steps.height} shown)"
st.caption(f"{total} steps with {ERROR_LABELS[error_type]}{shown}; select one to open its episode.")
picked = st.dataframe(
    steps,
    hide_index=True,
    on_select="rerun",
    selection_mode="single-row",
    key="errors_drill_steps",
)
links.open_step_link(steps, picked)
