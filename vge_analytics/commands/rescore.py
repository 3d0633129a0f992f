"""`vge rescore OUT --metrics-dir DIR`: what a metrics folder changes, run by run."""

from __future__ import annotations

import typer

from .. import reports, store
from ._bounds import command_limits
from ._incomplete import marked, warn_incomplete
from ._options import (
    by_option,
    flag_option,
    format_option,
    memory_limit_option,
    metric_names_option,
    metrics_dir_option,
    out_argument,
    parse_where,
    timeout_option,
    where_option,
)
from ._output import emit, emit_sections
from ._selection import check_where


def rescore(
    out: str = out_argument(),
    metrics_dir: str = metrics_dir_option(
        "The folder of metric files whose changes are reported (required, or $VGE_METRICS_DIR)."
    ),
    against: str = typer.Option(
        None,
        "--against",
        help="Compare with the metrics of this folder instead of the built-in metrics.",
    ),
    by: str = by_option(
        ",".join(reports.DEFAULT_RESCORE_BY),
        "Rank these groups (comma-separated columns, as vge metrics --by); default: runs.",
    ),
    metric_names: str = metric_names_option(
        "Only these of the metrics the folder changes or adds (comma-separated)."
    ),
    where: list[str] = where_option(),
    fmt: str = format_option(),
    timeout: float = timeout_option(),
    memory_limit: str = memory_limit_option(what="each query"),
    summary: bool = flag_option(
        "--summary",
        "Print one row per metric instead (change, Kendall's tau-b between the rankings, "
        "the groups whose rank moved); in json a list of such objects.",
    ),
) -> None:
    """What the metrics of a folder change, run by run, and how the rankings move.

    Per run, each changed or added metric before and after, the difference, the rank before
    and after; per metric, Kendall's tau-b between the two rankings and the runs whose rank
    moved.

    Rank 1 is the best value in the metric's direction; tied values share a rank. json and csv
    print the rows (a list of objects with metric, the group columns, before, after, delta,
    rank_before, rank_after), or with --summary the rankings; table, markdown and latex print
    both.
    """
    with command_limits(out, timeout, memory_limit):
        reports.check_format(fmt)
        filters = parse_where(where)
        check_where(out, filters, where)
        result = reports.rescore(
            out,
            metrics_dir,
            against=against,
            by=store.parse_by(by),
            where=filters,
            metrics=metric_names,
        )
        if not result.changes:
            typer.echo("The metrics folder changes no metric: nothing to report.", err=True)
        runs = warn_incomplete(out, filters.get("run_id"))
        if fmt in ("json", "csv"):
            table = result.summary if summary else marked(result.rows, runs, fmt, result.by)
            emit(table, fmt, marks=False)
            return
        sections = result.tables()
        sections["changes"] = marked(sections["changes"], runs, fmt, result.by)
        if summary:
            sections = {"rankings": sections["rankings"]}
        emit_sections(sections, fmt, fixed=True)


def register(app: typer.Typer) -> None:
    app.command("rescore")(rescore)
