"""Human vs VLM: two runs on the episodes both played, with clustered, paired intervals."""

import streamlit as st

from app import _charts as charts
from app import _data as data
from app import _lifecycle as page
from app import _links as links
from app import _sidebar as sidebar
from app import _tables as tables
from vge_analytics import AnalyticsError
from vge_analytics import dashboard as dash

st.title("Human vs VLM")
st.caption(
    "Metrics of both runs on their common episodes; the difference is human − model (as in "
    "the paper's tables) with a 95% paired interval that resamples devices, not episodes: "
    "the episodes of a device move together."
)

runs = data.runs()
humans, models = dash.run_choices(runs.filter(runs["run_id"].is_in(sidebar.runs_matching_facets(runs))))
c1, c2, c3 = st.columns([2, 2, 1])
human = c1.selectbox("Human (or reference) run", humans, key="hvv_human")
model = c2.selectbox("Model run", [r for r in models if r != human], key="hvv_model")
cluster = c3.selectbox("Resample", list(dash.CLUSTER_WORDS), key="hvv_cluster")
if human is None or model is None:
    st.info("This needs two runs.")
    page.stop()
try:
    cmp = data.compare(model, human, cluster=cluster)
except AnalyticsError as exc:
    page.show_error(exc)
    page.stop()

mc = cmp.mcnemar.row(0, named=True)
st.markdown(
    f"**{cmp.n_common} common episodes** ({cmp.n_only_a} only {model}, {cmp.n_only_b} only "
    f"{human}). Solved by both {mc['both']}, only {model} {mc['a_only']}, only {human} "
    f"{mc['b_only']}, neither {mc['neither']}; McNemar exact p = {mc['p_value']:.3g}, "
    f"clustered (by {cluster}) p = {mc['p_cluster']:.3g}."
)
st.caption(dash.interval_caption(cmp))
table = dash.comparison_rows(cmp.metrics, model, human, data.metric_set())
tables.number_table(table, key="hvv_metrics", every_row=True)
st.altair_chart(charts.side_by_side(cmp.metrics, model, human), width="content")
st.markdown(
    f"**{human} − {model}**, 95% interval resampling {dash.CLUSTER_WORDS[cluster]} "
    f"(green: {human} better, "
    f"red: {model} better, by each metric's direction)"
)
st.altair_chart(charts.diff_forest(cmp.metrics, model, human), width="content")

st.subheader("Error distribution")
errors = dash.error_difference_rows(cmp.errors, model, human)
tables.number_table(errors, digits=1)

st.subheader("Episodes that flip")
flips = dash.flip_rows(cmp.flips, model, human)
st.caption(
    f"{flips.height} episodes solved by one run only; select one to open it in the run that "
    "failed it (`run_id`), or both runs side by side."
)
picked = st.dataframe(
    flips, hide_index=True, on_select="rerun", selection_mode="single-row", key="hvv_flips"
)
links.open_step_link(flips, picked)
links.open_side_by_side_link(flips, picked, human, model)
