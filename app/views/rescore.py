"""Rescore: what the metrics folder the app runs with changes, group by group."""

import streamlit as st

from app import _charts as charts
from app import _data as data
from app import _lifecycle as page
from app import _pickers as pickers
from app import _sidebar as sidebar
from app import _tables as tables
from vge_analytics import AnalyticsError
from vge_analytics import dashboard as dash

st.title("Rescore")
st.caption(
    "Each metric the metrics folder changes or adds, before (built-in) and after (the folder's "
    "file): the value and the rank of every group (1 = best in the metric's direction; equal "
    "values share a rank), and Kendall's τ-b between the two rankings (1: same order, −1: "
    "reversed)."
)

folder = data.metrics_dir()
if folder is None:
    st.info(
        "The app runs with the built-in metrics only. Start it with "
        "`vge app OUT --metrics-dir DIR` (or set VGE_METRICS_DIR) to see what the metric "
        "files of DIR change."
    )
    page.stop()

c1, c2 = st.columns([2, 3])
with c1:
    by = pickers.group_by_picker("rescore_by")
try:
    result = data.rescore(by=list(by), where=sidebar.where())
except AnalyticsError as exc:
    page.show_error(exc)
    page.stop()
if not result.changes:
    st.info(f"The metric files of `{folder}` change no metric (same SQL as the built-ins).")
    page.stop()

rankings = dash.rescore_rankings(result)
tables.number_table(rankings, key="rescore_rankings", every_row=True)

names = rankings["metric"].to_list()
metric = c2.selectbox("Metric", names, key="rescore_metric")
slopes = dash.rank_slopes(result, metric)
if slopes.height:
    st.altair_chart(charts.rank_slopes(slopes, metric), width="content")

changes = dash.rescore_changes(result)
shown = changes.filter(changes["metric"] == metric)
tables.number_table(shown, key="rescore_changes")
st.download_button(
    "Download CSV (every metric)",
    result.rows.write_csv(),
    file_name="rescore.csv",
    mime="text/csv",
)
