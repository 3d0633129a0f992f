"""Significance: which runs differ (every pair, adjusted p-values, tied groups) and, where a
model was run with several seeds, its pass@k and pass^k."""

import streamlit as st

from app import _charts as charts
from app import _data as data
from app import _lifecycle as page
from app import _sidebar as sidebar
from app import _tables as tables
from vge_analytics import dashboard as dash

st.title("Significance")
st.caption(
    "Every pair of runs on the episodes both played: the difference of a metric with its "
    "interval, devices resampled (a device's episodes move together), and a p-value adjusted "
    "for the number of pairs. See docs/STATISTICS.md."
)

runs = data.runs()
facet_runs = sidebar.runs_matching_facets(runs)
c1, c2, c3, c4 = st.columns([3, 2, 2, 2])
chosen = c1.multiselect("Runs", facet_runs, placeholder="all runs (of the facet filter)")
metric = c2.selectbox("Metric", tables.all_metrics(), key="sig_metric")
by = c3.selectbox("Compare", ["run_id", "model"], key="sig_by")
correction = c4.selectbox("Correction", ["holm", "bh", "none"], key="sig_correction")
result = page.or_stop(
    data.compare_all, runs=sorted(chosen or facet_runs), by=by, metric=metric, correction=correction
)

st.markdown(dash.significance_caption(result))
tables.number_table(result.ranking, key="sig_ranking", every_row=True)
st.altair_chart(
    charts.pair_heatmap(dash.pair_matrix(result), dash.ranking_order(result), metric),
    width="content",
)
with st.expander("Every pair"):
    tables.number_table(result.pairs, key="sig_pairs")

st.subheader("Repeated runs")
repeated = page.or_stop(data.repeated, runs=sorted(chosen or facet_runs))
groups = dash.repeated_rows(repeated)
if groups.height:
    st.caption(
        "Runs of one model that differ only in their seed. pass@k: at least one of k runs "
        "solves the episode; pass^k: all k do (unbiased estimators over the n runs); bands are "
        "95% intervals with devices resampled."
    )
    tables.number_table(groups, key="sig_groups", every_row=True)
    st.altair_chart(charts.passk_lines(dash.passk_curves(repeated)))
else:
    st.caption(
        "No model here was run with several seeds (run.json differing only in `seed`): "
        "`vge synth --seeds 3` or `vge run --seed K` makes such runs."
    )
