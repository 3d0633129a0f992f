"""Episode viewer: step through one episode as the agent saw it, with the replay's verdicts."""

import functools

import streamlit as st

from app import _data as data
from app import _lifecycle as page
from app import _links as links
from app import _pickers as pickers
from app import _sidebar as sidebar
from app import _tables as tables
from vge_analytics import dashboard as dash

st.title("Episode viewer")
run_ids = sidebar.runs_matching_facets(data.runs())
links.apply_viewer_query(run_ids)
pickers.keep_choice("viewer_run", run_ids)
c1, c2 = st.columns([2, 3])
run = c1.selectbox("Run", run_ids, key="viewer_run")
if run is None:
    st.info("No run matches the facet filter.")
    page.stop()
episodes = data.episodes(where={"run_id": run}, columns=list(tables.EPISODE_COLUMNS))
if episodes.height == 0:
    st.info(f"Run {run} has no replayed episode.")
    page.stop()
pickers.keep_choice("viewer_episode", episodes["episode_id"].to_list())
episode = c2.selectbox(
    "Episode",
    episodes["episode_id"].to_list(),
    format_func=dash.episode_labels(episodes).get,
    key="viewer_episode",
)
ep = episodes.filter(episodes["episode_id"] == episode).row(0, named=True)
steps = data.viewer_steps(run, episode)  # free texts cut at dash.TEXT_CHARS characters
goals = data.goals(where={"run_id": run, "episode_id": episode})

m = st.columns([2, 1, 1, 1, 1])
m[0].metric("Result", dash.termination_label(ep["termination"]))
m[1].metric("Goals", f"{ep['goals_completed']} / {ep['n_goals']}")
m[2].metric("Steps (optimal)", f"{ep['L_act']} ({ep['L_opt']})")
m[3].metric("SPL", f"{ep['spl']:.2f}")
m[4].metric("State-F1", f"{ep['state_f1']:.2f}")

if steps.height == 0:
    st.info("This episode has no step.")
    page.stop()
step = pickers.step_slider(steps)
st.caption(f"{steps.height} steps, numbered 0–{steps.height - 1}")
row = steps.row(step, named=True)
links.set_viewer_query(run, episode, step)

left, right = st.columns([3, 2])
with left:
    if row["view_before"] is None:
        st.info("This step was logged after the episode ended (truncated): it was not replayed.")
    else:
        st.image(
            data.step_picture(run, episode, step),
            caption=dash.step_caption(row),
        )
with right:
    st.markdown(dash.step_markdown(row, goals))
    for text in dash.long_texts(row):
        st.caption(text.note)
        st.download_button(
            f"Download the whole {text.label}",
            data=functools.partial(
                dash.step_text, str(data.out_dir()), run, episode, step, text.field
            ),  # read when clicked: the page holds only the cut text
            file_name=f"{run}-{episode}-step{step}-{text.field}.txt",
            mime="text/plain",
            icon=":material/download:",
            on_click="ignore",
            key=f"viewer_text_{text.field}",
        )
    classification = dash.step_classification(row)
    st.dataframe(classification, hide_index=True, height=tables.table_height(classification))
    if row["thinking"]:
        with st.expander("Thinking", expanded=True):
            st.text(row["thinking"])

st.download_button(
    "Download episode as MCAP (Foxglove)",
    data=functools.partial(dash.episode_mcap, str(data.out_dir()), run, episode),
    file_name=f"{run}-{episode}.mcap",
    mime="application/octet-stream",
    icon=":material/download:",
    on_click="ignore",
)
with st.expander("All steps of the episode"):
    st.dataframe(steps.select(tables.STEP_COLUMNS), hide_index=True)
