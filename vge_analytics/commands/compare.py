"""`vge compare OUT RUN_A RUN_B`: paired comparison on common episodes, clustered intervals
and corrected tests; `vge compare OUT --all`: every pair, a ranking and its tied groups
(docs/STATISTICS.md)."""

from __future__ import annotations

import typer

from replay import ConfigError

from ..reports import (
    CLUSTER_UNITS,
    CORRECTIONS,
    DEFAULT_ALPHA,
    DEFAULT_CLUSTER,
    DEFAULT_CORRECTION,
    DEFAULT_RESAMPLES,
    DEFAULT_SEED,
)
from ._benchmarks import allow_option, refusal_hinted
from ._bounds import command_limits
from ._incomplete import warn_incomplete
from ._options import (
    episode_ids,
    format_option,
    ids_option,
    memory_limit_option,
    metric_names_option,
    metrics_dir_option,
    out_argument,
    timeout_option,
)
from ._output import emit_sections


def compare(
    out: str = out_argument(),
    run_a: str = typer.Argument(None, help="Baseline run id (A)."),
    run_b: str = typer.Argument(None, help="Compared run id (B); differences are B - A."),
    metric_names: str = metric_names_option("Metrics (default: all)."),
    every: bool = typer.Option(
        False,
        "--all",
        help="Every pair of runs (or of --by groups), a ranking and its tied groups.",
    ),
    runs: str | None = ids_option("--runs", "With --all: only these runs, comma-separated."),
    by: str = typer.Option(
        "run_id",
        "--by",
        help="With --all: compare groups of runs sharing this runs column (model).",
    ),
    metric: str = typer.Option("SR", "--metric", help="With --all: the metric compared."),
    cluster: str = typer.Option(
        DEFAULT_CLUSTER,
        "--cluster",
        help=f"What is resampled: {', '.join(CLUSTER_UNITS)} (episode: independent episodes).",
    ),
    correction: str = typer.Option(
        DEFAULT_CORRECTION,
        "--correction",
        help=f"How p-values are adjusted for the family of tests: {', '.join(CORRECTIONS)}.",
    ),
    alpha: float = typer.Option(
        DEFAULT_ALPHA, "--alpha", help="With --all: adjusted p below it is a difference."
    ),
    seed: int = typer.Option(DEFAULT_SEED, "--seed", help="Bootstrap and permutation seed."),
    resamples: int = typer.Option(DEFAULT_RESAMPLES, "--resamples", help="Bootstrap resamples."),
    metrics_dir: str = metrics_dir_option(),
    fmt: str = format_option(),
    timeout: float = timeout_option(),
    memory_limit: str = memory_limit_option(what="each query"),
    allow_different: bool = allow_option(),
) -> None:
    """Paired comparison of two runs on the episodes both have, or of every pair (--all).

    Metrics of A and B, B - A with 95% cluster bootstrap intervals (devices resampled by
    default), clustered and naive standard errors, the design effect, a cluster sign-flip
    p-value per metric adjusted across the metrics, McNemar's exact and clustered tests on
    success, error-distribution difference in percentage points, flipped episodes.
    """
    from ..reports import check_format
    from ..reports import compare as compute_compare

    with command_limits(out, timeout, memory_limit), refusal_hinted():
        check_format(fmt)
        if every:
            if run_a is not None or run_b is not None:
                raise ConfigError("--all compares every run: give no RUN_A RUN_B (--runs chooses)")
            chosen = episode_ids(runs, "--runs")
            options = dict(
                cluster=cluster,
                correction=correction,
                seed=seed,
                resamples=resamples,
                allow_different_benchmarks=allow_different,
            )
            _every_pair(out, chosen, by, metric, alpha, options, metrics_dir, fmt)
            return
        if run_a is None or run_b is None:
            raise ConfigError("compare needs RUN_A and RUN_B, or --all")
        result = compute_compare(
            out,
            run_a,
            run_b,
            metrics=metric_names,
            seed=seed,
            resamples=resamples,
            cluster=cluster,
            correction=correction,
            metrics_dir=metrics_dir,
            allow_different_benchmarks=allow_different,
        )
        warn_incomplete(out, [run_a, run_b])
        emit_sections(result.sections(), fmt)


def _every_pair(
    out: str,
    runs: list[str] | None,
    by: str,
    metric: str,
    alpha: float,
    options: dict,
    metrics_dir: str,
    fmt: str,
) -> None:
    """`vge compare OUT --all`: every pair of runs (or of `by` groups), ranked."""
    from ..reports import compare_all

    result = compare_all(
        out, runs=runs, by=by, metric=metric, alpha=alpha, metrics_dir=metrics_dir, **options
    )
    warn_incomplete(out, runs)
    emit_sections(result.sections(), fmt)


def register(app: typer.Typer) -> None:
    app.command("compare")(compare)
