"""Plumbing shared by the dashboard pages: which OUT, the sidebar, cached analytics calls.

Every number a page shows comes from `call(name, ...)`: one function of the analytics API
(`API` below), run through `st.cache_data` with the OUT path and `out_version(OUT)` (the hash
of OUT's manifest) in the key, so a re-replay of OUT invalidates the cache. The functions
that compute metrics (`METRIC_API`) also get the app's metrics folder (`--metrics-dir`, else
`$VGE_METRICS_DIR`), with the fingerprint of its definitions in the key.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, NamedTuple

import pandas as pd
import polars as pl
import streamlit as st

import vge_analytics as va
from vge_analytics import dashboard as dash
from vge_analytics import play
from vge_analytics.metrics._set import default_folder
from vge_analytics.store._isolated import default_max_queries
from vge_analytics.store._limits import APP_MAX_ROWS, APP_TIMEOUT, CLI_TIMEOUT, SqlLimits

API: dict[str, Callable[..., Any]] = {
    "metrics": va.metrics,
    "error_distribution": va.error_distribution,
    "error_groups": va.error_groups,
    "switch_classes": va.switch_classes,
    "compare": va.compare,
    "sql_preview": dash.sql_preview,
    "runs": va.runs,
    "facets": va.facets,
    "episodes": va.episodes,
    "goals": va.goals,
    "episode_steps": va.episode_steps,
    "error_step_sample": dash.error_step_sample,
    "out_summary": dash.out_summary,
    "column_values": dash.column_values,
    "step_picture": dash.step_picture,
    "episode_mcap": dash.episode_mcap,
    "interaction_views": dash.interaction_views,
    "click_points": dash.click_points,
    "scatter_boxes": dash.scatter_boxes,
    "view_picture": dash.view_picture,
    "table_columns": dash.table_columns_frame,
    "sweep_size": dash.sweep_size,
    "computed_sweep": dash.computed_sweep,
    "rescore": va.rescore,
}
"""The functions pages may call, by name: first argument OUT, the rest as given."""

METRIC_API: frozenset[str] = frozenset({"metrics", "compare", "computed_sweep", "rescore"})
"""The functions of `API` that take `metrics_dir` (given the app's folder by `call`)."""

PAGES: dict[str, str] = {
    "leaderboard": "views/leaderboard.py",
    "errors": "views/errors.py",
    "navigation": "views/navigation.py",
    "grounding": "views/grounding.py",
    "budgets": "views/budgets.py",
    "human_vs_vlm": "views/human_vs_vlm.py",
    "rescore": "views/rescore.py",
    "episode_viewer": "views/episode_viewer.py",
    "sql": "views/sql.py",
}
"""Page files, relative to the entry file (for links between pages)."""


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


@st.cache_data(show_spinner=False, max_entries=1024)
def _cached(name: str, out: str, version: str, args: tuple, kwargs: dict) -> Any:
    del version  # part of the cache key only
    with va.query_time_limit(query_timeout()):
        return API[name](out, *args, **kwargs)


def query_timeout(argv: Sequence[str] | None = None) -> float | None:
    """The pages' analytics queries' time limit: `--query-timeout` among the script arguments
    (what `vge app` passes; 0: none), else the command line's default."""
    value = script_option("query-timeout", argv)
    return CLI_TIMEOUT if value is None else (float(value) or None)


def call(name: str, *args: Any, **kwargs: Any) -> Any:
    """`API[name](OUT, *args, **kwargs)`, cached per (OUT, manifest hash, arguments); the
    metric functions also get `metrics_dir` (the app's folder, see `metrics_dir`)."""
    out = out_dir()
    version = dash.out_version(out)
    if name in METRIC_API:
        kwargs = {**kwargs, "metrics_dir": metrics_dir()}
        version += "/" + metric_set().fingerprint
    return _cached(name, str(out), version, args, kwargs)


def metrics_dir(argv: Sequence[str] | None = None) -> str | None:
    """The metrics folder: `--metrics-dir` among the script arguments (what `vge app
    --metrics-dir` passes), else `$VGE_METRICS_DIR`, else None (the built-in metrics)."""
    return script_option("metrics-dir", argv) or default_folder()


def metric_set() -> va.MetricSet:
    """The metrics every page shows: the built-ins with the app's folder (read once per
    process, again when a file of the folder changes)."""
    return va.load_metrics(metrics_dir())


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


def end_of_page() -> None:
    """An invisible last element: when the browser shows it, the page's script has finished.

    It carries the number of the session's script run, so a browser can tell the end of the
    run it triggered from the end of the previous one."""
    n = st.session_state.get("_vge_runs", 0) + 1
    st.session_state["_vge_runs"] = n
    st.markdown(f'<div id="{END_MARKER}" data-run="{n}"></div>', unsafe_allow_html=True)


# ----------------------------------------------------------------------------- sidebar


def sidebar() -> bool:
    """The OUT indicator and the run-facet filters; False (after saying why) if OUT is unusable."""
    try:
        out = out_dir()
        summary = call("out_summary")
        facets = call("facets")
    except va.AnalyticsError as exc:
        st.sidebar.error("No usable replay output")
        show_error(exc)
        return False
    try:
        metrics = metric_set()
    except va.MetricFileError as exc:
        st.sidebar.error("Unusable metrics folder")
        show_error(exc)
        return False
    with st.sidebar:
        st.caption(f"**OUT** `{out}`")
        st.caption(
            f"{summary.runs} runs · {summary.episodes} episodes · {summary.steps} steps · "
            f"engine {summary.engine_version}"
            + (f" · {summary.quarantined} quarantined" if summary.quarantined else "")
        )
        if metrics.folder is not None:
            st.caption(f"**Metrics** built-in + `{metrics.folder}`")
        useful = {c: v for c, v in facets.items() if len(v) > 1}
        if useful:
            st.markdown("**Run facets** (filter every page)")
            for column, values in useful.items():
                st.multiselect(
                    column.removeprefix("meta_"),
                    values,
                    key=f"facet:{column}",
                    placeholder="all",
                    format_func=value_label,
                )
    return True


def value_label(value: Any) -> str:
    """How a facet or column value reads in a picker (null as `(none)`)."""
    return "(none)" if value is None else str(value)


def facet_filters() -> dict[str, list]:
    """{facet column: chosen values} from the sidebar (empty choice = no filter)."""
    chosen = {}
    for key, value in st.session_state.items():
        if isinstance(key, str) and key.startswith("facet:") and value:
            chosen[key.removeprefix("facet:")] = list(value)
    return dict(sorted(chosen.items()))


def where(**extra: Sequence[Any] | None) -> dict[str, list]:
    """The facet filters plus the page's own (`column=[values]`; empty means no filter)."""
    filters = facet_filters()
    for column, values in extra.items():
        if values:
            filters[column] = list(values)
    return filters


# ---------------------------------------------------------------------------- grouping

GROUPINGS: dict[str, tuple[str, ...]] = {
    "run": ("run_id", "model"),
    "model": ("model",),
    "agent kind": ("agent_kind",),
    "category": ("category",),
    "goal count": ("n_goals",),
}


def group_by_picker(key: str, *, label: str = "Group by") -> tuple[str, ...]:
    """A selectbox of groupings (run, model, agent kind, category, goal count, each facet)."""
    options = dict(GROUPINGS)
    for column in call("facets"):
        options[f"model × {column.removeprefix('meta_')}"] = ("model", column)
    choice = st.selectbox(label, list(options), key=key)
    return options[choice]


class Selection(NamedTuple):
    """What a page's filter row chose: runs, categories, the grouping and the filters."""

    runs: list[str]
    categories: list[str]
    by: tuple[str, ...]
    where: dict[str, list]


def filter_row(key: str) -> Selection:
    """The row of pickers shared by the analysis pages: runs, category, group by."""
    c1, c2, c3 = st.columns([3, 2, 2])
    runs = c1.multiselect("Runs", call("runs")["run_id"].to_list(), placeholder="all runs")
    categories = c2.multiselect(
        "Category", call("column_values", "episodes", "category"), placeholder="all"
    )
    with c3:
        by = group_by_picker(f"{key}_by")
    return Selection(runs, categories, by, where(run_id=runs, category=categories))


def labelled(df: pl.DataFrame, by: Sequence[str]) -> pl.DataFrame:
    """`df` with a `group` label column first (the run id when grouped by run; the run_id
    column itself is then dropped as a duplicate)."""
    out = df.with_columns(dash.group_labels(df, by))
    drop = {"group", "run_id"} if "run_id" in by and "model" in by and len(by) == 2 else {"group"}
    return out.select("group", *[c for c in df.columns if c not in drop])


# ------------------------------------------------------------------------------ tables


def number_config(df: pl.DataFrame, digits: int = 2) -> dict[str, Any]:
    """Column formats showing every float column of `df` with `digits` decimals."""
    return {
        c: st.column_config.NumberColumn(format=f"%.{digits}f")
        for c, t in df.schema.items()
        if t in (pl.Float64, pl.Float32)
    }


def table_height(df: pl.DataFrame) -> int:
    """Pixel height showing every row of a small table without a scrollbar."""
    return 38 + 35 * df.height


def metric_column_config(names: Sequence[str]) -> dict[str, Any]:
    """Column formats for metric columns: 2 decimals, header with the paper's arrow (and ✎
    or ＋ for a metric the metrics folder overrides or adds), the definition on hover."""
    metrics = metric_set()
    headers = dash.metric_headers(names, metrics)
    return {
        name: st.column_config.NumberColumn(
            headers[name], format="%.2f", help=dash.metric_help(name, metrics)
        )
        for name in names
    }


def best_styler(df: pl.DataFrame, metric_names: Sequence[str]) -> Any:
    """A pandas Styler of `df` with each metric's best value(s) in bold on green."""
    best = dash.best_rows(df, metric_names, metric_set())
    pdf = df.to_pandas()

    def style(column: pd.Series) -> list[str]:
        rows = set(best.get(str(column.name), []))
        return [
            "font-weight: bold; background-color: rgba(38, 191, 77, 0.25)" if i in rows else ""
            for i in range(len(column))
        ]

    present = [m for m in metric_names if m in pdf.columns]
    return pdf.style.apply(style, subset=present).format(precision=2, na_rep="—", subset=present)


def all_metrics() -> tuple[str, ...]:
    """Every metric the pages show: the built-ins, then those the metrics folder adds."""
    return metric_set().names


# ----------------------------------------------------------------------------- steps

STEP_COLUMNS: tuple[str, ...] = (
    "run_id",
    "episode_id",
    "step",
    "goal_index",
    "view_before",
    "action_raw",
    "feedback_kind",
    "error_type",
    "error_detail",
    "state_before",
    "state_after",
)
"""Columns of the drill-down step tables (what a person scans to pick a step)."""
MAX_ROWS = 500
"""Rows a drill-down table shows (the caption gives the full count)."""


def selected_row(df: pl.DataFrame, selection: Any) -> dict | None:
    """The row a single-row dataframe selection points at, or None."""
    try:
        rows = selection.selection.rows
    except AttributeError:
        return None
    if not rows or rows[0] >= df.height:
        return None
    return df.row(rows[0], named=True)


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
        PAGES["episode_viewer"],
        label=label,
        icon=":material/movie:",
        query_params=viewer_query(row["run_id"], row["episode_id"], step),
    )


# --------------------------------------------------------------------- small helpers

LAMBDA_CHOICES: tuple[float, ...] = (1, 1.5, 2, 2.5, 3, 4, 5, 6, 8, 10)
"""λ values the budgets page offers."""


def sweep_workers(size: int) -> int:
    """Processes for a sweep: two for a large one (the machine's cores permitting)."""
    return 1 if size <= dash.SWEEP_AUTO_LIMIT else max(1, min(2, os.cpu_count() or 1))


def runs_matching_facets(runs: pl.DataFrame) -> list[str]:
    """Run ids that pass the sidebar's facet filters."""
    return dash.runs_matching(runs, facet_filters())


def view_label(views: pl.DataFrame, view: str) -> str:
    n = views.filter(views["view"] == view)["interactions"].sum()
    return f"{view}: {n} clicks"


def click_summary(points: pl.DataFrame) -> str:
    counts = dash.click_counts(points)
    total = sum(counts.values())
    parts = ", ".join(f"{n} {outcome}" for outcome, n in counts.items())
    return (
        f"{total} clicks ({parts}). Green boxes: components that were the nearest target of a "
        "click shown; grey: the view's other components."
    )


# ---------------------------------------------------------------------- episode viewer

EPISODE_COLUMNS: tuple[str, ...] = (
    "episode_id",
    "device_id",
    "category",
    "n_goals",
    "goals_completed",
    "success",
    "termination",
    "L_act",
    "L_opt",
    "spl",
    "state_f1",
)
_VIEWER_KEYS = {"run": "viewer_run", "episode": "viewer_episode", "step": "viewer_step"}


def apply_viewer_query(runs: Sequence[str]) -> None:
    """Open the episode the URL names (`?run=...&episode=...&step=...`) when the URL changed
    (a drill-down link or a pasted address); the pickers keep the user's choice otherwise."""
    query = {k: st.query_params.get(k) for k in _VIEWER_KEYS}
    if query["run"] not in runs or query == st.session_state.get("viewer_applied"):
        return
    st.session_state["viewer_applied"] = query
    st.session_state["viewer_run"] = query["run"]
    if query["episode"]:
        st.session_state["viewer_episode"] = query["episode"]
    try:
        st.session_state["viewer_step"] = int(query["step"] or 0)
    except ValueError:
        st.session_state["viewer_step"] = 0


def set_viewer_query(run: str, episode: str, step: int) -> None:
    """Keep the URL in step with the pickers, so the address can be shared."""
    query = viewer_query(run, episode, step)
    st.session_state["viewer_applied"] = {k: query.get(k) for k in _VIEWER_KEYS}
    if dict(st.query_params) != query:
        st.query_params.from_dict(query)


def step_slider(steps: pl.DataFrame) -> int:
    """The step picker (a slider over the episode's steps); returns the chosen position."""
    last = steps.height - 1
    current = st.session_state.get("viewer_step", 0)
    if not isinstance(current, int) or not 0 <= current <= last:
        st.session_state["viewer_step"] = 0
    if last == 0:
        st.session_state["viewer_step"] = 0
        st.caption("One step.")
        return 0
    return int(st.slider("Step", 0, last, key="viewer_step"))


# --------------------------------------------------------------------------------- SQL


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


def sql_max_queries(argv: Sequence[str] | None = None) -> int:
    """How many SQL page queries run at once across all sessions: `vge app
    --sql-max-queries` (passed on as a script argument), else as many as fit in memory at the
    page's limits (`default_max_queries`)."""
    given = script_option("sql-max-queries", argv)
    return int(given) if given else default_max_queries(sql_settings(argv)[0])


def load_example() -> None:
    """Callback of the examples picker: put the chosen query in the query box."""
    name = st.session_state.get("sql_example")
    if name in dash.EXAMPLE_QUERIES:
        st.session_state["sql_query"] = dash.EXAMPLE_QUERIES[name]


def init_state(key: str, value: Any) -> None:
    """Give a widget its first value through the session state (before it is drawn)."""
    if key not in st.session_state:
        st.session_state[key] = value


def keep_choice(key: str, options: Sequence[Any]) -> None:
    """Forget a picker's remembered value when it is no longer one of its options."""
    if key in st.session_state and st.session_state[key] not in options:
        del st.session_state[key]
