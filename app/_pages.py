"""The dashboard's pages, listed once: the entry file routes to them, the pages link to one
another by their key. A new page is one line here and its file in `views/`."""

from __future__ import annotations

from typing import NamedTuple

import streamlit as st


class Page(NamedTuple):
    """One page of the dashboard."""

    key: str
    """How the other pages name it (links)."""
    file: str
    """Its script, relative to the entry file."""
    title: str
    icon: str


PAGES: tuple[Page, ...] = (
    Page("leaderboard", "views/leaderboard.py", "Leaderboard", ":material/leaderboard:"),
    Page("errors", "views/errors.py", "Errors", ":material/error:"),
    Page("navigation", "views/navigation.py", "Navigation", ":material/explore:"),
    Page("grounding", "views/grounding.py", "Grounding", ":material/my_location:"),
    Page("budgets", "views/budgets.py", "Budgets", ":material/timeline:"),
    Page("human_vs_vlm", "views/human_vs_vlm.py", "Human vs VLM", ":material/compare_arrows:"),
    Page("significance", "views/significance.py", "Significance", ":material/rule:"),
    Page("side_by_side", "views/side_by_side.py", "Side by side", ":material/splitscreen:"),
    Page("rescore", "views/rescore.py", "Rescore", ":material/swap_vert:"),
    Page("episode_viewer", "views/episode_viewer.py", "Episode viewer", ":material/movie:"),
    Page("sql", "views/sql.py", "SQL", ":material/database:"),
)
"""The pages over OUT, in the order of the navigation; the first opens by default."""

PLAY = Page("play", "views/play.py", "Play", ":material/touch_app:")
"""The page `vge play` opens, alone."""


def page_file(key: str) -> str:
    """The script of the page called `key` (for `st.page_link`)."""
    for page in (*PAGES, PLAY):
        if page.key == key:
            return page.file
    raise KeyError(f"no page {key!r}")


def navigation(pages: tuple[Page, ...]) -> st.navigation:
    """Streamlit's navigation over `pages`, the first the default."""
    return st.navigation(
        [
            st.Page(p.file, title=p.title, icon=p.icon, default=i == 0)
            for i, p in enumerate(pages)
        ]
    )


__all__ = ["PAGES", "PLAY", "Page", "navigation", "page_file"]
