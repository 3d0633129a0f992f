"""`vge metrics OUT`: the paper's main table (PROTOCOL §6), plus PSR and the distance metrics;
`vge metrics --list`: the metrics themselves (built-in, overridden, added)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import typer

from replay import VGEError

from .. import reports, store
from ._answers import Answer, Question, question
from ._bounds import command_limits
from ._incomplete import PEOPLE_FORMATS, marked, marked_rows, say, warn_incomplete
from ._options import (
    by_option,
    flag_option,
    format_option,
    memory_limit_option,
    metric_names_option,
    metrics_dir_option,
    parse_where,
    timeout_option,
    where_option,
)
from ._output import emit, for_people, printed
from ._selection import check_where

if TYPE_CHECKING:
    import polars as pl

    from ..metrics import MetricSet

LIST_COLUMNS: tuple[str, ...] = (
    "metric",
    "title",
    "version",
    "direction",
    "unit",
    "grain",
    "source",
    "definition",
)
"""What `vge metrics --list` shows of each metric."""


def list_table(available: MetricSet) -> pl.DataFrame:
    """The metrics of a set as `--list` shows them: source is `built-in`, or the file that
    defines (adds or overrides) the metric."""
    import polars as pl

    from ..metrics import metric_table

    table = metric_table(available).with_columns(
        source=pl.when(pl.col("origin") == "built-in")
        .then(pl.lit("built-in"))
        .otherwise(pl.col("source"))
    )
    return table.select(LIST_COLUMNS)


def metrics_command(
    out: str = typer.Argument(
        None, help="Replay output directory (vge replay --out); not needed with --list."
    ),
    by: str = by_option(
        ",".join(store.DEFAULT_BY),
        "Group by these columns of runs/episodes (comma-separated), e.g. model,category "
        "or meta_history; step columns such as action_type work with step metrics only.",
    ),
    metric_names: str = metric_names_option(
        "Metrics to show, comma-separated (default: all twelve, in the paper's order, "
        "then those --metrics-dir adds); "
        "'main' = the paper's Table 2 (SR SSR SPL State-F1 EIR TIR VSPS GVPE EER); "
        "'continuation' = RecoveryRate and StepsToRecover (continuation runs).",
    ),
    where: list[str] = where_option(),
    metrics_dir: str = metrics_dir_option(),
    list_metrics: bool = flag_option(
        "--list",
        "List the metrics instead: name, title, version, direction, unit, grain, source "
        "(built-in, or the file that defines or overrides it) and definition.",
    ),
    fmt: str = format_option(),
    timeout: float = timeout_option(),
    memory_limit: str = memory_limit_option(what="each query"),
) -> None:
    """The paper's main table: its twelve metrics per run or per any grouping.

    SR SSR SPL State-F1 EIR TIR VSPS GVPE EER PSR AvgDist AvgWDist (and the metrics of
    --metrics-dir); in table, markdown and latex the best value of each metric is bold and
    the second best underlined.
    """
    options = dict(locals())  # every option as given: what a kept answer is keyed by
    asked = None if list_metrics or out is None else _kept_question(out, options, metrics_dir)
    if asked is not None:
        answer = asked.answer()
        if answer is not None:
            answer.show(say)
            return
    with command_limits(out, timeout, memory_limit):
        reports.check_format(fmt)
        from ..metrics import load_metrics

        available = load_metrics(metrics_dir)
        if list_metrics:
            title = "Metrics" + (f" (built-in and {available.folder})" if available.folder else "")
            emit(list_table(available), fmt, title=title, marks=False)
            return
        if out is None:
            import click  # (here: imported with the command, it costs each start a hundredth)

            raise click.UsageError("Missing argument 'OUT' (or --list to list the metrics).")
        answer = _answer(out, by, metric_names, where, available, fmt)
    if asked is not None:
        asked.keep(answer)


def _kept_question(out: str, options: dict, metrics_dir: str | None) -> Question | None:
    """The question the options ask of OUT, whose answer may be kept (`_answers`), or None;
    None too when the metrics folder cannot be read (the command then says why). A folder is
    told by its files' text (`folder_fingerprint`), not loaded: no DuckDB to check it."""
    from ..metrics import folder_fingerprint

    try:
        return question(out, "metrics", options, lambda: folder_fingerprint(metrics_dir))
    except (VGEError, OSError):
        return None


def _answer(
    out: str, by: str, metric_names: str | None, where: list[str], available, fmt: str
) -> Answer:
    """The metrics of OUT per group, printed (its warnings as they come, then the table),
    and what was printed."""
    from ..metrics import metrics

    said: list[str] = []

    def warn(line: str) -> None:
        said.append(line)
        say(line)

    by_cols = store.parse_by(by)
    chosen = metric_names  # `main` and `continuation` stand for their metrics
    filters = parse_where(where)
    check_where(out, filters, where, warn=warn)
    df = metrics(out, by=by_cols, metrics=chosen, where=filters, metrics_dir=available)
    runs = warn_incomplete(out, filters.get("run_id"), warn=warn)
    if fmt in PEOPLE_FORMATS:
        incomplete = [r.run_id for r in runs if r.incomplete]
        flags = df["run_id"].is_in(incomplete) if "run_id" in df.columns else None
        df = for_people(df, by_cols)
        if flags is not None:  # the run's label: its id, or its model when that was dropped
            df = marked_rows(df, "run_id" if "run_id" in df.columns else "model", flags)
    else:
        df = marked(df, runs, fmt, by_cols)
    held = reports.metrics_held([c for c in df.columns if c in available], available)
    shown = printed(df, fmt, title=f"{held}: {reports.ARROWS_LEGEND}", metric_set=available)
    shown.show()
    return Answer(tuple(said), shown)


def register(app: typer.Typer) -> None:
    app.command("metrics")(metrics_command)
