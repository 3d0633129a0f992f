"""How a page's script runs: an analytics error shown to the person (no traceback), a page
that ends early (`stop`), and the invisible marker every run ends with (`end_of_page`), which
the browser tests and the render-time benchmark wait for."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

import streamlit as st

import vge_analytics as va

R = TypeVar("R")


def show_error(exc: Exception) -> None:
    """An analytics error as a message for people (no traceback)."""
    st.error(str(exc), icon=":material/error:")


END_MARKER = "vge-page-done"
"""id of the invisible element every script run ends with (`end_of_page`)."""


class PageStopped(Exception):  # noqa: N818 - a control-flow signal, like st.stop's
    """Raised by `stop()`: the page has said all it can; the entry file still ends the run
    with its marker (st.stop would drop everything after it)."""


def stop() -> None:
    """End the page here (the entry file catches this and finishes the run)."""
    raise PageStopped


def or_stop(fn: Callable[..., R], *args: Any, **kwargs: Any) -> R:
    """`fn(*args, **kwargs)`; when it raises an analytics error (runs that cannot be
    compared, a query past its limit), the error is shown and the page ends there."""
    try:
        return fn(*args, **kwargs)
    except va.AnalyticsError as exc:
        show_error(exc)
        stop()
        raise  # not reached: stop() raises


def end_of_page() -> None:
    """An invisible last element: when the browser shows it, the page's script has finished.

    It carries the number of the session's script run, so a browser can tell the end of the
    run it triggered from the end of the previous one."""
    n = st.session_state.get("_vge_runs", 0) + 1
    st.session_state["_vge_runs"] = n
    st.markdown(f'<div id="{END_MARKER}" data-run="{n}"></div>', unsafe_allow_html=True)


__all__ = ["END_MARKER", "PageStopped", "end_of_page", "or_stop", "show_error", "stop"]
