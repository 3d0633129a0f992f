"""The Streamlit dashboard (`vge app`, `vge play`): routing in `streamlit_app.py` over the page
list of `_pages.py`, one thin page per file in `views/`, the data they show in `_data.py`
(cached calls of the analytics), charts in `_charts.py`, and the plumbing the pages share,
one job a module: `_lifecycle` (a page's run), `_sidebar`, `_pickers`, `_tables`, `_links`,
`_settings` (what the commands pass the app).

The command line starts the app through the two names below; importing this package imports
nothing else.

The page directory is deliberately not called `pages/`: Streamlit treats a `pages/` folder
next to the entry file as an old-style multipage app until some session has called
`st.navigation`, so a deep link such as `/episode_viewer?run=...` opened first on a fresh
server would run the page without the entry file (no sidebar, no facet filters).
"""

from __future__ import annotations

from pathlib import Path

ENTRY_FILE = Path(__file__).resolve().with_name("streamlit_app.py")
"""The file `streamlit run` serves."""


def warm(out: str) -> None:
    """Import what every page imports (Streamlit, Altair, pandas, polars, the analytics), in
    the server process before it listens: the pages' scripts then find the modules loaded.
    Then fork the SQL page's standby query process for the app's OUT
    (`_settings.keep_sql_standby`), which opens OUT while the server warms up, and open OUT
    here as the pages will (`_data.open_as_the_pages_do`); a bad OUT is left to the pages to
    report."""
    import contextlib

    from vge_analytics import AnalyticsError

    from . import _charts, _data, _lifecycle, _links, _pages, _pickers, _settings, _sidebar, _tables

    del _charts, _lifecycle, _links, _pages, _pickers, _sidebar, _tables
    with contextlib.suppress(AnalyticsError):
        _settings.keep_sql_standby()
    _data.open_as_the_pages_do(out)


__all__ = ["ENTRY_FILE", "warm"]
