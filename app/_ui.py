"""Plumbing shared by the dashboard pages: which OUT, the sidebar, cached analytics calls.

Every number a page shows comes from a function of `app/_data.py`: a function of the
analytics API or of `vge_analytics.dashboard` wrapped by `cached`, which runs it through
`st.cache_data` with the OUT path and `out_version(OUT)` (the hash of OUT's manifest) in the
key, so a re-replay of OUT invalidates the cache. The functions that compute metrics also
get the app's metrics folder (`--metrics-dir`, else `$VGE_METRICS_DIR`), with the
fingerprint of its definitions in the key.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from typing import Any, NamedTuple, TypeVar

import pandas as pd
import polars as pl
import streamlit as st

import vge_analytics as va
from app import _data as data
from app._data import metric_set, out_dir, script_option
from vge_analytics import dashboard as dash
from vge_analytics import play
from vge_analytics.store import (
    APP_MAX_ROWS,
    APP_TIMEOUT,
    SqlLimits,
    default_max_queries,
    describe_filters,
)

R = TypeVar("R")

PAGES: dict[str, str] = {
    "leaderboard": "views/leaderboard.py",
    "errors": "views/errors.py",
    "navigation": "views/navigation.py",
    "grounding": "views/grounding.py",
    "budgets": "views/budgets.py",
    "human_vs_vlm": "views/human_vs_vlm.py",
    "side_by_side": "views/side_by_side.py",
    "rescore": "views/rescore.py",
    "episode_viewer": "views/episode_viewer.py",
    "sql": "views/sql.py",
}
"""Page files, relative to the entry file (for links between pages)."""


# --------------------------------------------------------------------------------- OUT


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


# ----------------------------------------------------------------------------- sidebar


def sidebar() -> bool:
    """The OUT indicator and the run-facet filters; False (after saying why) if OUT is unusable."""
    try:
        out = out_dir()
        summary = data.out_summary()
        facets = data.facets()
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
    refuse_empty(filters)
    return filters


def refuse_empty(filters: dict[str, list]) -> None:
    """Say in one line, instead of an empty table, that the filters select no row (and
    end the page there); warn about values no row holds."""
    if not filters:
        return
    check = data.selection_check(filters)
    line = check.line(f"The selection ({describe_filters(filters)})")
    if line:
        st.warning(line, icon=":material/filter_alt_off:")
    if check.empty:
        stop()


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
    for column in data.facets():
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
    runs = c1.multiselect("Runs", data.runs()["run_id"].to_list(), placeholder="all runs")
    categories = c2.multiselect(
        "Category", data.column_values("episodes", "category"), placeholder="all"
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


def number_table(
    df: pl.DataFrame, *, digits: int = 2, key: str | None = None, every_row: bool = False
) -> None:
    """A table of numbers with `digits` decimals; `every_row` shows all rows, no scrollbar."""
    st.dataframe(
        df,
        hide_index=True,
        column_config=number_config(df, digits),
        height=table_height(df) if every_row else "auto",
        key=key,
    )


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


def cost_column_config() -> dict[str, Any]:
    """Column formats for the leaderboard's cost columns: dollars, 4 decimals."""
    return {
        name: st.column_config.NumberColumn(header, format="$%.4f")
        for name, header in dash.COST_COLUMNS.items()
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
    """Run ids that pass the sidebar's facet filters (the page ends with one line when
    none does)."""
    filters = facet_filters()
    refuse_empty(filters)
    return dash.runs_matching(runs, filters)


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


# ------------------------------------------------------------------------ side by side

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
        PAGES["side_by_side"],
        label=f"Side by side: {row['episode_id']} in {run_a} and {run_b}",
        icon=":material/splitscreen:",
        query_params=side_query(run_a, run_b, row["episode_id"]),
    )


def _go_to_step(step: int) -> None:
    st.session_state["sbs_step"] = step


def side_step_slider(n_steps: int, marks: dict[int, list[str]]) -> int:
    """The shared step picker of the Side by side page, over `n_steps` (the longer log),
    each step named with its marks (first difference, first errors), and a button per
    marked step that jumps there; returns the chosen step."""
    current = st.session_state.get("sbs_step", 0)
    if not isinstance(current, int) or not 0 <= current < n_steps:
        st.session_state["sbs_step"] = 0
    buttons = st.columns(max(len(marks), 1))
    for column, (step, texts) in zip(buttons, sorted(marks.items()), strict=False):
        column.button(
            f"Step {step}: {', '.join(texts)}",
            key=f"sbs_jump_{step}",
            on_click=_go_to_step,
            args=(step,),
            disabled=step >= n_steps,
        )
    if n_steps <= 1:
        st.session_state["sbs_step"] = 0
        st.caption("One step.")
        return 0
    return int(
        st.select_slider(
            "Step (both runs)",
            options=list(range(n_steps)),
            format_func=lambda k: dash.step_label(k, marks),
            key="sbs_step",
        )
    )


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
