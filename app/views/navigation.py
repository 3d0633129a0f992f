"""Navigation: how view switches went (NP/PN/NN/PP, the paper's switch-view figure), VSPS, GVPE."""

import streamlit as st

from app import _charts as charts
from app import _data as data
from app import _pickers as pickers
from app import _tables as tables
from vge_analytics import dashboard as dash

st.title("Navigation")
st.caption(
    "Each successful Switch_view is classed by whether a target component of the current goal "
    "is visible (P) or not (N) in the start and end views: **NP** found the target, **PN** lost "
    "it, **NN** searched in vain, **PP** kept it. VSPS: switches per completed goal within "
    "episodes; GVPE: all switches per completed goal (both ↓)."
)

chosen_runs, categories, by, where = pickers.filter_row("navigation")

classes = tables.labelled(data.switch_classes(by=list(by), where=where), by)
ratios = tables.labelled(data.metrics(by=list(by), metrics=["VSPS", "GVPE"], where=where), by)
order = ratios["group"].to_list()

if pickers.charts_wanted(len(order), classes.height + 2 * len(order), "navigation_charts"):
    st.altair_chart(charts.switch_stacked(classes, order))
    left, right = st.columns(2)
    left.altair_chart(charts.ratio_bars(ratios, "VSPS", order))
    right.altair_chart(charts.ratio_bars(ratios, "GVPE", order))
summary = dash.switch_summary(classes, ratios)
st.dataframe(
    summary,
    hide_index=True,
    column_config={  # shares with one decimal, as the charts' tooltips
        **tables.number_config(summary, 1),
        **tables.metric_column_config(["VSPS", "GVPE"]),
    },
)
