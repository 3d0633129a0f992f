"""`vge compare OUT RUN_A RUN_B`: paired comparison on common episodes, bootstrap CIs."""

from __future__ import annotations

import typer

from ..reports import DEFAULT_RESAMPLES, DEFAULT_SEED
from ._incomplete import warn_incomplete
from ._options import (
    format_option,
    metric_names_option,
    metrics_dir_option,
    out_argument,
    timeout_option,
)
from ._output import emit_sections


def compare(
    out: str = out_argument(),
    run_a: str = typer.Argument(..., help="Baseline run id (A)."),
    run_b: str = typer.Argument(..., help="Compared run id (B); differences are B - A."),
    metric_names: str = metric_names_option("Metrics (default: all)."),
    seed: int = typer.Option(DEFAULT_SEED, "--seed", help="Bootstrap seed."),
    resamples: int = typer.Option(DEFAULT_RESAMPLES, "--resamples", help="Bootstrap resamples."),
    metrics_dir: str = metrics_dir_option(),
    fmt: str = format_option(),
    timeout: float = timeout_option(),
) -> None:
    """Paired comparison of two runs on the episodes both have.

    Metrics of A and B, B - A with paired bootstrap 95% CIs, McNemar's exact test on
    success, error-distribution difference in percentage points, flipped episodes.
    """
    from ..reports import check_format
    from ..reports import compare as compute_compare
    from ..store import query_time_limit

    with query_time_limit(timeout):
        check_format(fmt)
        result = compute_compare(
            out,
            run_a,
            run_b,
            metrics=metric_names,
            seed=seed,
            resamples=resamples,
            metrics_dir=metrics_dir,
        )
        warn_incomplete(out, [run_a, run_b])
        emit_sections(result.sections(), fmt)


def register(app: typer.Typer) -> None:
    app.command("compare")(compare)
