"""`vge passk OUT`: repeated runs of one agent (seeds) as groups, their pass@k and pass^k,
mean SR, between-seed spread and an interval over seeds and devices (docs/STATISTICS.md)."""

from __future__ import annotations

import typer

from ..reports import (
    CLUSTER_UNITS,
    DEFAULT_CLUSTER,
    DEFAULT_RESAMPLES,
    DEFAULT_SEED,
)
from ._benchmarks import allow_option, refusal_hinted
from ._bounds import command_limits
from ._options import (
    episode_ids,
    flag_option,
    format_option,
    ids_option,
    memory_limit_option,
    out_argument,
    timeout_option,
)
from ._output import emit_sections


def passk(
    out: str = out_argument(),
    runs: str | None = ids_option("--runs", "Only these runs, comma-separated."),
    group_by: str | None = typer.Option(
        None,
        "--group-by",
        metavar="COLUMN,...",
        help="Runs-table columns a group agrees on (default: every run.json field but the "
        "run id, meta.seed and the run's totals).",
    ),
    k: int = typer.Option(None, "--k", help="The largest k (default: each group's runs)."),
    per_episode: bool = flag_option("--per-episode", "Also each episode's c of n."),
    cluster: str = typer.Option(
        DEFAULT_CLUSTER, "--cluster", help=f"What is resampled: {', '.join(CLUSTER_UNITS)}."
    ),
    seed: int = typer.Option(DEFAULT_SEED, "--seed", help="Bootstrap seed."),
    resamples: int = typer.Option(DEFAULT_RESAMPLES, "--resamples", help="Bootstrap resamples."),
    fmt: str = format_option(),
    timeout: float = timeout_option(),
    memory_limit: str = memory_limit_option(what="each query"),
    allow_different: bool = allow_option(),
) -> None:
    """pass@k and pass^k of repeated runs (runs differing only in their seed).

    Per group: its runs, the episodes all of them played, the mean SR and its between-seed
    standard deviation with an interval over seeds and devices; pass@k (any of k runs
    succeeds) and pass^k (all k succeed) for k = 1..n; how many episodes c of the n runs
    solved.
    """
    from ..reports import check_format, repeated

    with command_limits(out, timeout, memory_limit), refusal_hinted():
        check_format(fmt)
        columns = episode_ids(group_by, "--group-by") if group_by is not None else None
        result = repeated(
            out,
            runs=episode_ids(runs, "--runs"),
            group_by=columns,
            k=k,
            cluster=cluster,
            seed=seed,
            resamples=resamples,
            allow_different_benchmarks=allow_different,
        )
        emit_sections(result.sections(per_episode), fmt)


def register(app: typer.Typer) -> None:
    app.command("passk")(passk)
