"""The data every page shows: each a function of the analytics API or of
`vge_analytics.dashboard`, called as `data.metrics(by=..., where=...)` with the app's OUT
filled in and the result cached (`cached`), typed as the function it wraps.

OUT, the query time limit and the metrics folder come from the script arguments `vge app`
passes after `--` (`script_option`).
"""

from __future__ import annotations

import contextlib
import functools
import os
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, Concatenate, ParamSpec, TypeVar

import streamlit as st

import vge_analytics as va
from vge_analytics import dashboard as dash
from vge_analytics.metrics import default_folder
from vge_analytics.store import CLI_TIMEOUT, check_selection, kept_result

P = ParamSpec("P")
R = TypeVar("R")


# --------------------------------------------------------------------------------- OUT


def script_option(name: str, argv: Sequence[str] | None = None) -> str | None:
    """The value of `--name VALUE` (or `--name=VALUE`) among the script arguments (what
    `vge app` passes after `--`)."""
    args = list(sys.argv[1:] if argv is None else argv)
    flag = f"--{name}"
    for i, arg in enumerate(args):
        if arg == flag and i + 1 < len(args):
            return args[i + 1]
        if arg.startswith(f"{flag}="):
            return arg.split("=", 1)[1]
    return None


def out_argument(argv: Sequence[str] | None = None) -> str:
    """OUT from the script arguments (`-- --out OUT`), else `$VGE_APP_OUT`, else the default."""
    return script_option("out", argv) or os.environ.get(dash.OUT_ENV) or dash.DEFAULT_OUT


def out_dir() -> Path:
    """The checked OUT directory (raises `OutputDirError` with what to run if it is not one)."""
    return dash.check_out(out_argument())


# -------------------------------------------------------------------------- caching


_WRAPPED: dict[str, Callable[..., Any]] = {}
"""The functions `cached` wraps, by qualified name (the cache key names the function)."""


_KEPT: set[str] = set()
"""The functions whose results are also kept on disk beside OUT (`cached(kept=True)`)."""


@st.cache_data(show_spinner=False, max_entries=1024)
def _cached(key: str, out: str, version: str, args: tuple, kwargs: dict) -> Any:
    return _call(key, out, args, kwargs, version)


SQL_RESULTS_KEPT = 8
"""Results of the SQL page the server keeps (each at most `vge_analytics.store.RESULT_BYTES`,
so 256 MB at most), apart from the other pages' many small ones."""


@st.cache_data(show_spinner=False, max_entries=SQL_RESULTS_KEPT)
def _cached_sql(key: str, out: str, version: str, args: tuple, kwargs: dict) -> Any:
    del version  # part of the cache key only
    return _call(key, out, args, kwargs)


def _call(key: str, out: str, args: tuple, kwargs: dict, version: str = "") -> Any:
    """`fn(OUT, *args, **kwargs)` within the pages' bounds; for a kept function, read from
    OUT's cache folder when a server on the same OUT computed it before (`kept_result`, keyed
    by OUT's contents, the arguments and `version`, whose metric fingerprint is the
    definitions')."""
    fn = _WRAPPED[key]
    with query_bounds():
        if key not in _KEPT:
            return fn(out, *args, **kwargs)
        return kept_result(
            out, key, (args, kwargs), lambda: fn(out, *args, **kwargs), version=version
        )


def query_bounds(argv: Sequence[str] | None = None) -> contextlib.AbstractContextManager:
    """The bounds of the pages' analytics queries (`va.query_limits`): `--query-timeout`, the
    SQL page's memory limit (`--sql-memory-limit`, DuckDB's and the process cap's), and a
    query holding a metric file's SQL in a query process of its own, sharing the SQL page's
    slots (`--sql-max-queries`): the server's process is never capped, its other visitors
    never fail an allocation."""
    given = script_option("sql-max-queries", argv)
    return va.query_limits(
        memory=script_option("sql-memory-limit", argv),
        timeout=query_timeout(argv),
        isolated=True,
        max_queries=int(given) if given else None,
    )


def open_as_the_pages_do(out: str) -> None:
    """Open OUT and run the leaderboard's default query within the pages' bounds
    (`query_bounds`, from the script arguments), in the server before it listens: a store is
    kept per memory limits, so one opened with the default limits was opened again by the
    first page (its manifest read and hashed, its tables listed: 0.5 s at 100x)."""
    with query_bounds():
        try:
            va.runs(out)
            va.metrics(out)
        except va.AnalyticsError:
            pass  # the app reports a bad OUT to the person, in the page


def query_timeout(argv: Sequence[str] | None = None) -> float | None:
    """The pages' analytics queries' time limit: `--query-timeout` among the script arguments
    (what `vge app` passes; 0: none), else the command line's default."""
    value = script_option("query-timeout", argv)
    return CLI_TIMEOUT if value is None else (float(value) or None)


def cached(
    fn: Callable[Concatenate[Any, P], R],
    *,
    metrics: bool = False,
    sql: bool = False,
    kept: bool = False,
) -> Callable[P, R]:
    """`fn(OUT, ...)` as a page calls it, `fn(...)`: OUT is the app's, and the result is
    cached per (OUT, manifest hash, arguments). With `metrics`, `fn` also gets `metrics_dir`
    (the app's folder, see `metrics_dir`), and the folder's fingerprint joins the key. With
    `sql` (user queries' results), only the last `SQL_RESULTS_KEPT` are kept. With `kept`
    (a function of OUT's tables alone, slow on a large OUT), the result is also kept on disk
    beside OUT, for the next server (`vge_analytics.store.kept_result`)."""
    key = f"{fn.__module__}.{fn.__qualname__}"
    _WRAPPED[key] = fn
    if kept:
        _KEPT.add(key)
    cache = _cached_sql if sql else _cached

    @functools.wraps(fn)
    def call(*args: P.args, **kwargs: P.kwargs) -> R:
        out = out_dir()
        version = dash.out_version(out)
        if metrics:
            kwargs = {**kwargs, "metrics_dir": metrics_dir()}  # type: ignore[assignment]
            version += "/" + metric_set().fingerprint
        return cache(key, str(out), version, args, kwargs)

    return call


def metrics_dir(argv: Sequence[str] | None = None) -> str | None:
    """The metrics folder: `--metrics-dir` among the script arguments (what `vge app
    --metrics-dir` passes), else `$VGE_METRICS_DIR`, else None (the built-in metrics)."""
    return script_option("metrics-dir", argv) or default_folder()


def metric_set() -> va.MetricSet:
    """The metrics every page shows: the built-ins with the app's folder (read once per
    process, again when a file of the folder changes)."""
    return va.load_metrics(metrics_dir())


# ------------------------------------------------------------------------ the data

metrics = cached(va.metrics, metrics=True, kept=True)
compare = cached(va.compare, metrics=True, kept=True)
compare_all = cached(va.compare_all, metrics=True, kept=True)
metric_intervals = cached(va.metric_intervals, metrics=True, kept=True)
repeated = cached(va.repeated, kept=True)
rescore = cached(va.rescore, metrics=True, kept=True)
computed_sweep = cached(dash.computed_sweep, metrics=True)
error_distribution = cached(va.error_distribution, kept=True)
switch_classes = cached(va.switch_classes, kept=True)
runs = cached(va.runs, kept=True)
facets = cached(dash.run_facets, kept=True)
episodes = cached(va.episodes, kept=True)
goals = cached(va.goals)
episode_steps = cached(va.episode_steps)
viewer_steps = cached(dash.viewer_steps)
out_summary = cached(dash.out_summary)
column_values = cached(dash.column_values, kept=True)
error_step_sample = cached(dash.error_step_sample, kept=True)
step_picture = cached(dash.step_picture)
pair_rows = cached(dash.pair_rows, kept=True)
side_picture = cached(dash.side_picture)
side_steps = cached(dash.side_steps)
interaction_views = cached(dash.interaction_views, kept=True)
click_points = cached(dash.click_points, kept=True)
scatter_boxes = cached(dash.scatter_boxes)
view_picture = cached(dash.view_picture)
table_columns = cached(dash.table_columns_frame, kept=True)
sweep_size = cached(dash.sweep_size, kept=True)
sql_preview = cached(dash.sql_preview, sql=True)
example_preview = cached(dash.example_preview, sql=True, kept=True)
completeness = cached(va.completeness, kept=True)
cost_table = cached(dash.cost_table, kept=True)
selection_check = cached(check_selection)
