"""What `vge app` and `vge play` pass the dashboard as script arguments: the Play page's
benchmark and run, the SQL page's limits; and the settings derived from them."""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import NamedTuple

import streamlit as st

from app._data import out_dir, script_option
from vge_analytics import dashboard as dash
from vge_analytics import play
from vge_analytics.store import (
    APP_MAX_ROWS,
    APP_TIMEOUT,
    SqlLimits,
    default_max_queries,
    keep_standby,
)


class PlayTarget(NamedTuple):
    """What `vge play` opened the app on."""

    bench: str
    run: str
    image_width: int | None
    """CSS pixels the view is shown at; None: the width of its column."""


def play_target(argv: Sequence[str] | None = None) -> PlayTarget | None:
    """BENCH, RUN and the image width when the app was opened by `vge play` (`-- --bench
    BENCH --run RUN [--image-width PX]`); None for the dashboard over OUT. Script options
    only, no environment variable: one left set in a shell would turn a later `vge app`
    into the Play page."""
    bench = script_option("bench", argv)
    if not bench:
        return None
    width = script_option("image-width", argv)
    return PlayTarget(
        bench,
        script_option("run", argv) or play.DEFAULT_RUN_DIR,
        int(width) if width else None,
    )


@st.cache_resource(show_spinner="Opening the benchmark…")
def human_run(bench: str, run: str) -> play.HumanRun:
    """The human run the Play page writes (one per server: its files are the state)."""
    return play.HumanRun.open(run, bench)


def sql_settings(argv: Sequence[str] | None = None) -> tuple[SqlLimits, int]:
    """The SQL page's limits and row cap, from `vge app --sql-timeout/--sql-memory-limit/
    --sql-max-rows` (passed on as script arguments); defaults 30 s, a quarter of the
    machine's memory, 10,000 rows."""
    timeout = script_option("sql-timeout", argv)
    rows = script_option("sql-max-rows", argv)
    limits = SqlLimits.make(
        memory=script_option("sql-memory-limit", argv),
        timeout=APP_TIMEOUT if timeout is None else float(timeout),
    )
    return limits, APP_MAX_ROWS if rows is None else int(rows)


def keep_sql_standby() -> None:
    """A standby query process for the SQL page of this server's OUT, within the page's
    limits (`vge_analytics.store.keep_standby`): `vge app` starts it when it opens OUT; a
    server started otherwise, with its first session. Nothing when one is kept already."""
    keep_standby(out_dir(), sql_settings()[0])


def sql_max_queries(argv: Sequence[str] | None = None) -> int:
    """How many SQL page queries run at once across all sessions: `vge app
    --sql-max-queries` (passed on as a script argument), else as many as fit in memory at the
    page's limits (`default_max_queries`)."""
    given = script_option("sql-max-queries", argv)
    return int(given) if given else default_max_queries(sql_settings(argv)[0])


def sweep_workers(size: int) -> int:
    """Processes for a sweep: two for a large one (the machine's cores permitting)."""
    return 1 if size <= dash.SWEEP_AUTO_LIMIT else max(1, min(2, os.cpu_count() or 1))


__all__ = [
    "PlayTarget",
    "human_run",
    "keep_sql_standby",
    "play_target",
    "sql_max_queries",
    "sql_settings",
    "sweep_workers",
]
