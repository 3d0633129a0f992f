"""Side by side: two runs on one common episode, on a shared step slider, with the planner's
optimal next action on each picture and the steps where the runs part and first err marked."""

import streamlit as st

from app import _data as data
from app import _lifecycle as page
from app import _links as links
from app import _pickers as pickers
from app import _sidebar as sidebar
from vge_analytics import dashboard as dash

st.title("Side by side")
st.caption(
    "Two runs on an episode both played, step by step: the view each saw with its click "
    "(red ×), the components it hit (orange), and the box of the planner's optimal next "
    "action from that run's situation (blue). The first difference (where the replays' state "
    "or view first differ) and each run's first error are marked on the slider."
)

runs = data.runs()
run_ids = sidebar.runs_matching_facets(runs)
links.apply_side_query(run_ids)
references, models = dash.run_choices(runs.filter(runs["run_id"].is_in(run_ids)))
c1, c2, c3 = st.columns([2, 2, 5])
pickers.keep_choice("sbs_a", references)
run_a = c1.selectbox("Run A", references, key="sbs_a")
others = [r for r in dict.fromkeys([*models, *references]) if r != run_a]
pickers.keep_choice("sbs_b", others)
run_b = c2.selectbox("Run B", others, key="sbs_b")
if run_a is None or run_b is None:
    st.info("This needs two runs.")
    page.stop()
rows = page.or_stop(data.pair_rows, run_a, run_b)  # e.g. runs without a common episode
ids = rows["episode_id"].to_list()
pickers.keep_choice("sbs_episode", ids)
pickers.init_state("sbs_episode", dash.default_episode(rows))
episode = c3.selectbox(
    f"Common episode ({len(ids)})", ids, format_func=dash.pair_labels(rows).get, key="sbs_episode"
)
row = rows.filter(rows["episode_id"] == episode).row(0, named=True)
st.markdown(dash.pair_summary(row))

both = {run_a: data.side_steps(run_a, episode), run_b: data.side_steps(run_b, episode)}
step = pickers.side_step_slider(max(s.height for s in both.values()), dash.step_marks(row))
links.set_side_query(run_a, run_b, episode, step)

for column, (name, run) in zip(st.columns(2), (("A", run_a), ("B", run_b)), strict=True):
    steps = both[run]
    with column:
        st.markdown(dash.side_heading(name, run, step, steps.height))
        ended = dash.ended_note(name, step, steps.height)
        if ended:
            st.info(ended)
        elif steps["view_before"][step] is None:
            st.info("This step was logged after the episode ended (truncated): not replayed.")
        else:
            picture = data.side_picture(run, episode, step)
            st.image(
                picture.png, caption=dash.side_caption(steps.row(step, named=True), picture.optimal)
            )
