"""`vge sweep OUT --lambdas 2,3,4,5`: SR and SSR per budget, by re-replaying the logs."""

from __future__ import annotations

import typer

from .. import reports
from ._bounds import command_limits
from ._options import (
    format_option,
    memory_limit_option,
    metric_names_option,
    metrics_dir_option,
    timeout_option,
)
from ._output import emit


def sweep(
    out: str = typer.Argument(..., help="Replay output directory (its manifest names the inputs)."),
    lambdas: str = typer.Option("2,3,4,5", "--lambdas", help="Comma-separated lambdas."),
    runs: str = typer.Option(None, "--runs", help="Only these run ids (comma-separated)."),
    metric_names: str = metric_names_option(
        "Episode metrics to compute.", ",".join(reports.DEFAULT_SWEEP_METRICS)
    ),
    workers: int = typer.Option(1, "--workers", min=1, help="Worker processes."),
    ray: str | None = typer.Option(
        None,
        "--ray",
        metavar="[ADDRESS]",
        help="Replay on a Ray cluster instead of local workers (as vge replay --ray).",
    ),
    metrics_dir: str = metrics_dir_option(),
    fmt: str = format_option(),
    timeout: float = timeout_option(),
    memory_limit: str = memory_limit_option(what="each query"),
) -> None:
    """SR and SSR per run at each lambda, by re-replaying the logs.

    Also the gain over the smallest lambda. A lambda above what a run's logs support (an
    episode hit its recorded budget and its log stops there) is refused.
    """
    with command_limits(out, timeout, memory_limit):
        reports.check_format(fmt)
        run_ids = [r.strip() for r in runs.split(",") if r.strip()] if runs else None
        df = reports.sweep(
            out,
            lambdas,
            runs=run_ids,
            metrics=metric_names.split(","),
            workers=workers,
            ray=ray,
            metrics_dir=metrics_dir,
        )
        emit(df, fmt, title="Budget sweep (gain over the smallest lambda)", marks=False)


def register(app: typer.Typer) -> None:
    app.command("sweep")(sweep)
