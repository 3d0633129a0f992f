"""Links between pages and the address they keep: a drill-down row opens the episode viewer or
the Side by side page on it, and the URL's query (`?run=...&episode=...&step=...`) and the
pickers follow each other, so an address can be shared."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import polars as pl
import streamlit as st

from app._pages import page_file
from app._tables import selected_row


def viewer_query(run_id: str, episode_id: str, step: int | None = None) -> dict[str, str]:
    """Query parameters that open the episode viewer on an episode (and step)."""
    query = {"run": str(run_id), "episode": str(episode_id)}
    if step is not None:
        query["step"] = str(int(step))
    return query


def open_step_link(df: pl.DataFrame, selection: Any) -> None:
    """A link to the episode viewer for the selected row (run_id, episode_id[, step])."""
    row = selected_row(df, selection)
    if row is None:
        return
    step = row.get("step")
    label = f"Open {row['episode_id']} of {row['run_id']}" + (
        f" at step {step}" if step is not None else ""
    )
    st.page_link(
        page_file("episode_viewer"),
        label=label,
        icon=":material/movie:",
        query_params=viewer_query(row["run_id"], row["episode_id"], step),
    )


_VIEWER_KEYS = {"run": "viewer_run", "episode": "viewer_episode", "step": "viewer_step"}


def apply_viewer_query(runs: Sequence[str]) -> None:
    """Open the episode the URL names (`?run=...&episode=...&step=...`) when the URL changed
    (a drill-down link or a pasted address); the pickers keep the user's choice otherwise."""
    _apply_query(_VIEWER_KEYS, "viewer_applied", runs)


def set_viewer_query(run: str, episode: str, step: int) -> None:
    """Keep the URL in step with the pickers, so the address can be shared."""
    _set_query(viewer_query(run, episode, step), _VIEWER_KEYS, "viewer_applied")


def _apply_query(keys: dict[str, str], applied: str, runs: Sequence[str]) -> None:
    """Put the URL's values (`keys`: query parameter -> widget key) into the pickers when
    the URL changed since they were last applied (`applied`: where that is remembered) and
    every run it names (parameters `run`, `a`, `b`) is one of `runs`. `step` is a number
    (0 when it is not one); an absent value leaves its picker as it is."""
    query = {k: st.query_params.get(k) for k in keys}
    named = [query[k] for k in ("run", "a", "b") if k in keys]
    if any(r not in runs for r in named) or query == st.session_state.get(applied):
        return
    st.session_state[applied] = query
    for name, key in keys.items():
        if name == "step":
            try:
                st.session_state[key] = int(query[name] or 0)
            except ValueError:
                st.session_state[key] = 0
        elif query[name]:
            st.session_state[key] = query[name]


def _set_query(query: dict[str, str], keys: dict[str, str], applied: str) -> None:
    """Show `query` in the URL, remembered as applied (so it is not applied back)."""
    st.session_state[applied] = {k: query.get(k) for k in keys}
    if dict(st.query_params) != query:
        st.query_params.from_dict(query)


_SIDE_KEYS = {"a": "sbs_a", "b": "sbs_b", "episode": "sbs_episode", "step": "sbs_step"}


def side_query(run_a: str, run_b: str, episode_id: str, step: int | None = None) -> dict[str, str]:
    """Query parameters that open the Side by side page on two runs' episode (and step)."""
    query = {"a": str(run_a), "b": str(run_b), "episode": str(episode_id)}
    if step is not None:
        query["step"] = str(int(step))
    return query


def apply_side_query(runs: Sequence[str]) -> None:
    """Open the runs and episode the URL names (`?a=...&b=...&episode=...&step=...`) when
    the URL changed (a link from Human vs VLM, a pasted address)."""
    _apply_query(_SIDE_KEYS, "sbs_applied", runs)


def set_side_query(run_a: str, run_b: str, episode: str, step: int) -> None:
    """Keep the URL in step with the Side by side pickers, so the address can be shared."""
    _set_query(side_query(run_a, run_b, episode, step), _SIDE_KEYS, "sbs_applied")


def open_side_by_side_link(df: pl.DataFrame, selection: Any, run_a: str, run_b: str) -> None:
    """A link to the Side by side page for the selected row's episode in runs A and B."""
    row = selected_row(df, selection)
    if row is None:
        return
    st.page_link(
        page_file("side_by_side"),
        label=f"Side by side: {row['episode_id']} in {run_a} and {run_b}",
        icon=":material/splitscreen:",
        query_params=side_query(run_a, run_b, row["episode_id"]),
    )


__all__ = [
    "apply_side_query",
    "apply_viewer_query",
    "open_side_by_side_link",
    "open_step_link",
    "set_side_query",
    "set_viewer_query",
    "side_query",
    "viewer_query",
]
