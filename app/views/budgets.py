"""Budgets: how SR grows with the interaction budget (the paper's lambda figure)."""

import streamlit as st

from app import _charts as charts
from app import _data as data
from app import _lifecycle as page
from app import _pickers as pickers
from app import _settings as settings
from app import _sidebar as sidebar
from app import _tables as tables
from vge_analytics import AnalyticsError
from vge_analytics import dashboard as dash

st.title("Budgets")
st.caption(
    "Every episode is replayed again with budgets λ·C_opt for each λ; the curves show the SR "
    "gain over the smallest λ chosen (the paper normalises λ = 2 to zero). A λ above the one "
    "a run was recorded with needs logs that go beyond that budget."
)

runs = data.runs()
facet_runs = sidebar.runs_matching_facets(runs)
c1, c2, c3 = st.columns([3, 2, 2])
chosen = c1.multiselect("Runs", facet_runs, placeholder="all runs (of the facet filter)")
lambdas = c2.multiselect("λ values", pickers.LAMBDA_CHOICES, default=[2, 3, 4, 5], key="budgets_lambdas")
relative = c3.radio("Gain", ["percentage points", "relative %"], key="budgets_gain")
if len(lambdas) < 2 or not facet_runs:
    st.info("Choose at least two λ values and one run.")
    page.stop()

selected = sorted(chosen or facet_runs)
table = dash.stored_sweep(data.out_dir(), selected, lambdas, metrics_dir=data.metrics_dir())
if table is None:
    size = data.sweep_size(selected, lambdas)
    if size > dash.SWEEP_AUTO_LIMIT and not st.button(
        f"Compute the sweep: {size:,} episode replays, about "
        f"{size * dash.SWEEP_SECONDS_PER_REPLAY / 2:.0f} s",
        icon=":material/play_arrow:",
    ):
        st.info(
            "This sweep is large; it is computed once, then kept (also across restarts). "
            "Fewer runs or λ values make it faster."
        )
        page.stop()
    try:
        with st.spinner("Replaying every episode at each λ..."):
            table = data.computed_sweep(selected, lambdas, workers=settings.sweep_workers(size))
    except AnalyticsError as exc:
        page.show_error(exc)
        page.stop()

gain = dash.sweep_curves(table, relative=relative == "relative %")
title = f"SR gain over λ = {min(lambdas):g}" + (
    " (% of SR at that λ)" if relative == "relative %" else " (pp)"
)
st.altair_chart(charts.sweep_lines(gain, title))
tables.number_table(table)
