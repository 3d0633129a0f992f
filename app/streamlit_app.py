"""Entry file of the dashboard: routing only (`vge app [OUT]` runs it with `-- --out OUT`;
`vge play BENCH` with `-- --bench BENCH --run RUN`, and then it shows the Play page alone).

The sidebar shows which OUT is open and holds the run-facet filters every page applies.
Every run ends with an invisible marker (`ui.end_of_page`): browser tests and the render-time
benchmark wait for it.
"""

from __future__ import annotations

import contextlib

import streamlit as st

from app import _ui as ui
from vge_analytics import AnalyticsError


def run() -> None:
    st.set_page_config(page_title="VGE Analytics", page_icon=":material/analytics:", layout="wide")
    if ui.play_target() is not None:  # opened by `vge play`: the Play page alone
        play = st.Page("views/play.py", title="Play", icon=":material/touch_app:", default=True)
        with contextlib.suppress(ui.PageStopped):
            st.navigation([play]).run()
        ui.end_of_page()
        return
    page = st.navigation(
        [
            st.Page(
                "views/leaderboard.py",
                title="Leaderboard",
                icon=":material/leaderboard:",
                default=True,
            ),
            st.Page("views/errors.py", title="Errors", icon=":material/error:"),
            st.Page("views/navigation.py", title="Navigation", icon=":material/explore:"),
            st.Page("views/grounding.py", title="Grounding", icon=":material/my_location:"),
            st.Page("views/budgets.py", title="Budgets", icon=":material/timeline:"),
            st.Page(
                "views/human_vs_vlm.py", title="Human vs VLM", icon=":material/compare_arrows:"
            ),
            st.Page("views/significance.py", title="Significance", icon=":material/rule:"),
            st.Page("views/side_by_side.py", title="Side by side", icon=":material/splitscreen:"),
            st.Page("views/rescore.py", title="Rescore", icon=":material/swap_vert:"),
            st.Page("views/episode_viewer.py", title="Episode viewer", icon=":material/movie:"),
            st.Page("views/sql.py", title="SQL", icon=":material/database:"),
        ]
    )
    if ui.sidebar():
        try:
            page.run()
        except ui.PageStopped:  # a page said all it could (ui.stop)
            pass
        except AnalyticsError as exc:  # a query past its time limit, a metric that fails
            ui.show_error(exc)
    ui.end_of_page()


if __name__ == "__main__":
    run()
