"""Leaderboard: the paper's main table (and PSR, Avg Dist) for the selected runs."""

import streamlit as st

from app import _charts as charts
from app import _data as data
from app import _ui as ui
from vge_analytics import dashboard as dash

st.title("Leaderboard")
st.caption(
    "The paper's twelve metrics per group, computed from the replayed steps. Best value per column "
    "in bold green (↑ higher is better, ↓ lower). Click a header to sort."
)
note = dash.metrics_note(data.metric_set())
if note:
    st.caption(note)

runs = data.runs()
c1, c2, c3, c4 = st.columns([3, 2, 2, 2])
chosen_runs = c1.multiselect("Runs", runs["run_id"].to_list(), placeholder="all runs")
categories = c2.multiselect(
    "Category", data.column_values("episodes", "category"), placeholder="all"
)
goal_counts = c3.multiselect(
    "Goal count", data.column_values("episodes", "n_goals"), placeholder="all"
)
with c4:
    by = ui.group_by_picker("leaderboard_by")

where = ui.where(run_id=chosen_runs, category=categories, n_goals=goal_counts)
names = ui.all_metrics()
table = ui.labelled(data.metrics(by=list(by), where=where), by)
st.dataframe(
    ui.best_styler(table, names),
    hide_index=True,
    column_config=ui.metric_column_config(names),
    key="leaderboard_table",
)
st.download_button("Download CSV", table.write_csv(), file_name="leaderboard.csv", mime="text/csv")

st.subheader("Per metric")
long = dash.metrics_long(table, names, data.metric_set())
st.altair_chart(charts.metric_bars(long, names, table["group"].to_list()))
