"""Leaderboard: the paper's main table (and PSR, Avg Dist) for the selected runs."""

import streamlit as st

from app import _charts as charts
from app import _data as data
from app import _lifecycle as page
from app import _pickers as pickers
from app import _sidebar as sidebar
from app import _tables as tables
from replay.io import EPISODES_TABLE
from vge_analytics import dashboard as dash
from vge_analytics import reports

st.title("Leaderboard")
names = tables.all_metrics()
st.caption(
    f"{reports.metrics_held(names, data.metric_set())}. One row per group, computed "
    "from the replayed steps. Best value per column in bold green (↑ higher is better, ↓ lower). "
    "Click a header to sort. Runs that recorded their cost also get the cost per episode and "
    "per success."
)
note = dash.metrics_note(data.metric_set())
if note:
    st.caption(note)

runs = data.runs()
c1, c2, c3, c4 = st.columns([3, 2, 2, 2])
chosen_runs = c1.multiselect("Runs", runs["run_id"].to_list(), placeholder="all runs")
categories = c2.multiselect(
    "Category", data.column_values(EPISODES_TABLE, "category"), placeholder="all"
)
goal_counts = c3.multiselect(
    "Goal count", data.column_values(EPISODES_TABLE, "n_goals"), placeholder="all"
)
with c4:
    by = pickers.group_by_picker("leaderboard_by")

where = sidebar.where(run_id=chosen_runs, category=categories, n_goals=goal_counts)
done = data.completeness()
incomplete = dash.incomplete_note(done)
if incomplete:  # never shown as finished runs (PROTOCOL §10.3)
    st.warning(incomplete, icon=":material/warning:")
metrics = data.metrics(by=list(by), where=where)
metrics = dash.with_costs(metrics, data.cost_table(list(by), where), by)
table = dash.incomplete_groups(
    tables.labelled(metrics, by), by, [r.run_id for r in done if r.incomplete]
)
st.dataframe(
    tables.best_styler(table, names),
    hide_index=True,
    column_config={
        **tables.group_column_config(table),
        **tables.metric_column_config(names),
        **tables.cost_column_config(),
    },
    key="leaderboard_table",
    placeholder=reports.MISSING,
)
st.download_button("Download CSV", table.write_csv(), file_name="leaderboard.csv", mime="text/csv")

st.subheader("Intervals")
c1, c2 = st.columns([2, 6])
interval_metric = c1.selectbox("Metric", names, key="leaderboard_interval_metric")
intervals = page.or_stop(data.metric_intervals, metric=interval_metric, by=list(by), where=where)
c2.caption(
    f"{interval_metric} per group with its 95% interval from resampling devices (all of a "
    "drawn device's episodes: a device hard for one run is hard for its other episodes too), "
    "the clustered standard error and the design effect (its variance over the one of "
    "independent episodes)."
)
tables.number_table(dash.interval_rows(intervals, by, interval_metric), key="leaderboard_intervals")

st.subheader("Per metric")
long = dash.metrics_long(table, names, data.metric_set())
if pickers.charts_wanted(table.height, long.height, "leaderboard_charts"):
    st.altair_chart(charts.metric_bars(long, names, table["group"].to_list()))

st.subheader("Cost and success")
plane = dash.cost_frontier(data.cost_table(["run_id", "model"], where))
if plane.height:
    st.caption(
        "One point per run that recorded its tokens with prices: SR against the cost per "
        "episode. The line joins the runs no other run beats on both (cheaper and at least as "
        "successful): the cost–success frontier."
    )
    st.altair_chart(charts.cost_frontier(plane))
else:
    st.caption(
        "No run here recorded tokens with prices (`vge run --prompt-price ... "
        "--completion-price ...`; simulated and human runs have none): no cost to plot."
    )
