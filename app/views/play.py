"""Play: a person operates a device by clicking its views; every step goes to a human run."""

import streamlit as st
from streamlit_image_coordinates import streamlit_image_coordinates

import replay
from app import _lifecycle as page
from app import _settings as settings
from vge_analytics import play

st.title("Play")
target = settings.play_target() or settings.PlayTarget("", "", None)  # the entry file routes here with one
bench, run_dir = target.bench, target.run
try:
    desk = play.PlayState(settings.human_run(bench, run_dir), st.session_state)
    if desk.game() is not None:
        desk.click()  # the image's last click, if it is a new one
    game = desk.game()
    episode_id = desk.episode_id()
    statuses = {s.episode_id: s for s in desk.run.statuses()}
except replay.VGEError as exc:
    page.show_error(exc)
    page.stop()

with st.sidebar:
    played = sum(s.state == "finished" for s in statuses.values())
    unfinished = sum(s.state == "unfinished" for s in statuses.values())
    st.caption(f"**Benchmark** `{bench}`")
    st.caption(f"**Run** `{run_dir}` ({desk.run.header.run_id}, {desk.run.header.model})")
    st.caption(f"{played} of {len(statuses)} episodes played · {unfinished} unfinished")
    st.caption(f"Score it: `vge replay {run_dir} --bench {bench} --out OUT`")

c1, c2 = st.columns([5, 1], vertical_alignment="bottom")
c1.selectbox("Episode", list(statuses), format_func=lambda e: statuses[e].label(), key=desk.EPISODE)
c2.button("Next not played", on_click=desk.pick_next, icon=":material/skip_next:")
st.caption(statuses[episode_id].summary())

message = desk.message()
if message is not None:
    getattr(st, message[0])(message[1])

status = statuses[episode_id]
if game is None and status.state == "finished":
    st.success(play.result_text(desk.run.result(episode_id)))
    st.caption("Each episode is played once per run: pick another one.")
    page.stop()
if game is None and status.state == "unfinished":
    st.info(
        f"{status.steps} steps of this episode were played before, and it was not finished "
        "(the page was closed, or another episode was picked)."
    )
    b1, b2, _ = st.columns([1, 2, 3])
    b1.button("Resume", on_click=desk.resume, type="primary", icon=":material/play_arrow:")
    b2.button("Discard and start over", on_click=desk.discard, icon=":material/delete:")
    page.stop()
if game is None:
    page.stop()
if game.done:
    st.success(play.result_text(game.result))
    st.button("Next episode", on_click=desk.pick_next, type="primary", icon=":material/skip_next:")
    st.dataframe(play.history(game.records), hide_index=True)
    page.stop()

obs = game.observation
left, right = st.columns([3, 2])
with right:
    st.info(play.goal_text(obs), icon=":material/flag:")
    m1, m2, m3 = st.columns(3)
    m1.metric("Steps taken", obs["step"])
    m2.metric("Steps left", play.budget_left(obs["budget_global_left"]))
    m3.metric("Left for this goal", play.budget_left(obs["budget_local_left"]))
    last = game.last
    if last is not None:
        tone = play.FEEDBACK_TONES.get(last.feedback_kind, "info")
        getattr(st, tone)(f"Step {last.index}: `{last.action}`  \n{last.feedback}")
    chosen = st.radio(
        "A click on the image does", play.CLICK_ACTIONS, key=desk.ACTION, horizontal=True
    )
    if chosen == play.SWITCH_VIEW:
        views = list(obs["views"])
        st.selectbox(
            "View to switch to", views, index=views.index(desk.click_view()), key=desk.CLICK_VIEW
        )
    else:
        default, meaning = play.PARAM_HINTS[chosen]
        st.text_input("Parameters", default, key=desk.params_key(chosen), help=meaning)
    st.markdown("**Without a point**")
    view = st.selectbox("Switch to the view", list(obs["views"]), key=desk.VIEW)
    v1, v2, v3 = st.columns(3)
    v1.button("Switch view", on_click=desk.switch_view, args=(view,), help=play.SWITCH_VIEW)
    v2.button("Wait", on_click=desk.wait, help=f"{play.TIMED_WAIT}: let time pass")
    v3.button("Give up", on_click=desk.give_up, help="End this episode here")
with left:
    st.caption(f"The **{obs['view']}** view. {play.click_hint(chosen, desk.click_view())}")
    streamlit_image_coordinates(
        obs["image"],
        width=target.image_width or "stretch",
        key=desk.click_key(),
        png_compression_level=1,  # 30 kB a view instead of 1.7 MB uncompressed
        cursor="crosshair",
    )
    if game.records:
        st.dataframe(play.history(game.records), hide_index=True)
