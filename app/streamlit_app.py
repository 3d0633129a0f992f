"""Entry file of the dashboard: routing only (`vge app [OUT]` runs it with `-- --out OUT`;
`vge play BENCH` with `-- --bench BENCH --run RUN`, and then it shows the Play page alone).

The pages are listed once, in `_pages.py`. The sidebar shows which OUT is open and holds the
run-facet filters every page applies. Every run ends with an invisible marker
(`_lifecycle.end_of_page`): browser tests and the render-time benchmark wait for it.
"""

from __future__ import annotations

import contextlib

import streamlit as st

from app import _lifecycle as page
from app import _pages as pages
from app import _settings as settings
from app import _sidebar as sidebar
from vge_analytics import AnalyticsError


def run() -> None:
    st.set_page_config(page_title="VGE Analytics", page_icon=":material/analytics:", layout="wide")
    if settings.play_target() is not None:  # opened by `vge play`: the Play page alone
        with contextlib.suppress(page.PageStopped):
            pages.navigation((pages.PLAY,)).run()
        page.end_of_page()
        return
    chosen = pages.navigation(pages.PAGES)
    if sidebar.sidebar():
        settings.keep_sql_standby()  # (once per server: `vge app` did it, or the first session)
        try:
            chosen.run()
        except page.PageStopped:  # a page said all it could (page.stop)
            pass
        except AnalyticsError as exc:  # a query past its time limit, a metric that fails
            page.show_error(exc)
    page.end_of_page()


if __name__ == "__main__":
    run()
