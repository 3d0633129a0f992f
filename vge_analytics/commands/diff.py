"""`vge diff OUT RUN_A RUN_B`: two runs' trajectories episode by episode: where they part,
where each first erred."""

from __future__ import annotations

import typer

from .. import reports
from ._benchmarks import allow_option, refusal_hinted
from ._bounds import command_limits
from ._options import episode_ids, ids_option, memory_limit_option, out_argument, timeout_option
from ._output import emit, emit_sections

DIFF_FORMATS: tuple[str, ...] = ("table", "json", "csv", "markdown")


def diff(
    out: str = out_argument(),
    run_a: str = typer.Argument(..., help="Run A."),
    run_b: str = typer.Argument(..., help="Run B."),
    episodes: str = ids_option("--episodes", "Only these episodes (each must be in both runs)."),
    fmt: str = typer.Option(
        "table",
        "--format",
        "-f",
        help="Output format: table (for people), json (the rows only), csv or markdown.",
    ),
    timeout: float = timeout_option(),
    memory_limit: str = memory_limit_option(what="each query"),
    allow_different: bool = allow_option(),
) -> None:
    """Two runs' trajectories side by side, one row per common episode.

    Scored steps and success of each run, each run's first step with an error type, and the
    first step at which the replays' state or view differ (the shorter length when one run
    is a prefix of the other; empty when identical). A summary follows: episodes by
    (success_a, success_b), the median first difference, the error types at the first
    errors.
    """
    with command_limits(out, timeout, memory_limit), refusal_hinted():
        # not latex: a row per episode is no table for a paper
        reports.check_format(fmt, DIFF_FORMATS)
        result = reports.diff(
            out,
            run_a,
            run_b,
            episodes=episode_ids(episodes, "--episodes"),
            allow_different_benchmarks=allow_different,
        )
        if fmt == "json":  # the rows alone: what another tool reads
            emit(result.episodes, fmt)
        else:
            emit_sections(result.sections(), fmt)


def register(app: typer.Typer) -> None:
    app.command("diff")(diff)
