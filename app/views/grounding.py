"""Grounding: how close clicks land to their targets, and where they land on a device view."""

import streamlit as st

from app import _charts as charts
from app import _data as data
from app import _lifecycle as page
from app import _pickers as pickers
from app import _tables as tables
from vge_analytics import dashboard as dash

st.title("Grounding")
st.caption(
    "Avg Dist: mean distance (0..1000 scale) from a click to the nearest target box; "
    "Avg W-Dist weighs repeated failed attempts on the same target more (both ↓). "
    "EIR / TIR: share of interactions hitting any component / a target component (↑)."
)

chosen_runs, categories, by, where = pickers.filter_row("grounding")

names = ["AvgDist", "AvgWDist", "EIR", "TIR"]
table = tables.labelled(data.metrics(by=list(by), metrics=names, where=where), by)
order = table["group"].to_list()
if pickers.charts_wanted(len(order), 2 * len(order), "grounding_charts"):
    left, right = st.columns(2)
    left.altair_chart(charts.ratio_bars(table, "AvgDist", order))
    right.altair_chart(charts.ratio_bars(table, "AvgWDist", order))
st.dataframe(
    tables.best_styler(table, names), hide_index=True, column_config=tables.metric_column_config(names)
)

st.subheader("Click points on a device view")
views = data.interaction_views(where=where)
if views.height == 0:
    st.info("No interaction in the selection.")
    page.stop()
devices = dash.device_labels(views)
d1, d2 = st.columns(2)
device = d1.selectbox(
    "Device (most clicked first)", list(devices), format_func=devices.get, key="grounding_device"
)
device_views = views.filter(views["device_id"] == device)
view = d2.selectbox(
    "View",
    device_views["view"].to_list(),
    format_func=lambda v: tables.view_label(device_views, v),
    key="grounding_view",
)
points = data.click_points(device, view, where=where)
boxes = data.scatter_boxes(device, view, dash.clicked_targets(points))
picture = data.view_picture(device, view)
st.altair_chart(charts.click_scatter(picture, boxes, points), width="content")
st.caption(tables.click_summary(points))
