"""`vge power OUT RUN_A RUN_B` and `vge power OUT --rate R`: the smallest difference a
comparison detects, and the devices and episodes needed to detect `--delta` points
(docs/STATISTICS.md)."""

from __future__ import annotations

import typer

from replay import ConfigError

from ..reports import (
    CLUSTER_UNITS,
    DEFAULT_CLUSTER,
    DEFAULT_DELTA,
    DEFAULT_POWER,
)
from ._benchmarks import allow_option, refusal_hinted
from ._bounds import command_limits
from ._options import (
    format_option,
    memory_limit_option,
    metrics_dir_option,
    out_argument,
    timeout_option,
)
from ._output import emit


def power(
    out: str = out_argument(),
    run_a: str = typer.Argument(None, help="A run id (with RUN_B: plan from their difference)."),
    run_b: str = typer.Argument(None, help="Another run id."),
    rate: float = typer.Option(
        None, "--rate", help="Without runs: the success rate to plan around (0.5 for 50%)."
    ),
    delta: float = typer.Option(
        DEFAULT_DELTA, "--delta", help="The difference to detect, in the metric's unit (points)."
    ),
    alpha: float = typer.Option(0.05, "--alpha", help="Level of the two-sided test."),
    power_: float = typer.Option(DEFAULT_POWER, "--power", help="Chance of detecting --delta."),
    icc: float = typer.Option(
        None,
        "--icc",
        help="With --rate: the intra-cluster correlation of success (default: measured on "
        "OUT's runs).",
    ),
    metric: str = typer.Option("SR", "--metric", help="With runs: the metric compared."),
    cluster: str = typer.Option(
        DEFAULT_CLUSTER, "--cluster", help=f"The clusters: {', '.join(CLUSTER_UNITS)}."
    ),
    metrics_dir: str = metrics_dir_option(),
    fmt: str = format_option(),
    timeout: float = timeout_option(),
    memory_limit: str = memory_limit_option(what="each query"),
    allow_different: bool = allow_option(),
) -> None:
    """How large a difference a comparison can detect, and how many devices it needs.

    With RUN_A RUN_B: from their paired difference's clustered standard error on the common
    episodes. With --rate: for planning, from OUT's cluster sizes and an intra-cluster
    correlation.
    """
    from ..reports import check_format, plan, power_of_pair

    with command_limits(out, timeout, memory_limit), refusal_hinted():
        check_format(fmt)
        if (run_a is None) != (run_b is None):
            raise ConfigError("power takes two runs (RUN_A RUN_B), or none with --rate")
        if run_a is not None:
            if rate is not None or icc is not None:
                raise ConfigError(
                    "--rate and --icc plan without runs: give them without RUN_A RUN_B"
                )
            table = power_of_pair(
                out,
                run_a,
                run_b,
                metric=metric,
                delta=delta,
                alpha=alpha,
                power=power_,
                cluster=cluster,
                metrics_dir=metrics_dir,
                allow_different_benchmarks=allow_different,
            )
        else:
            if rate is None:
                raise ConfigError("power needs RUN_A RUN_B, or --rate to plan without runs")
            table = plan(
                out, rate=rate, delta=delta, icc=icc, alpha=alpha, power=power_, cluster=cluster
            )
        emit(table, fmt, marks=False)


def register(app: typer.Typer) -> None:
    app.command("power")(power)
