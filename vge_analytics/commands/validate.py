"""`vge validate BENCH [RUN...]`: report every problem of a benchmark and its runs."""

from __future__ import annotations

from typing import TYPE_CHECKING

import typer

import replay

from ._options import max_record_bytes_option

if TYPE_CHECKING:
    from rich.console import Console


def _report(console: Console, problems: list[replay.Problem]) -> tuple[int, int]:
    from rich.markup import escape

    errors = warnings = 0
    for p in problems:
        if p.severity == "error":
            errors += 1
            tag = "[bold red]error[/]  "
        else:
            warnings += 1
            tag = "[yellow]warning[/]"
        console.print(f"{tag} {escape(str(p))}", highlight=False, soft_wrap=True)
    return errors, warnings


def validate(
    bench: str = typer.Argument(
        ..., help="Benchmark directory (ssm/, tasks.jsonl, ...): a path or a URI (s3://...)."
    ),
    runs: list[str] = typer.Argument(None, help="Run directories to check against it."),
    max_record_bytes: int = max_record_bytes_option("is an error"),
) -> None:
    """Check SSMs, UCSMs, tasks and run logs; exit 1 with a report if anything is wrong."""
    from rich.console import Console

    console = Console(highlight=False)
    problems = replay.validate_benchmark(bench)
    opened = replay.Benchmark.open(bench)
    for run in runs or []:
        problems.extend(replay.validate_run(run, opened, max_record_bytes=max_record_bytes))
    errors, warnings = _report(console, problems)
    n_ssm = len(opened.ssm_paths)
    n_tasks = len(opened.tasks)
    summary = (
        f"{n_ssm} SSM(s), {n_tasks} task(s), {len(runs or [])} run(s): "
        f"{errors} error(s), {warnings} warning(s)"
    )
    if errors:
        console.print(f"[bold red]FAILED[/] {summary}")
        raise typer.Exit(1)
    console.print(f"[bold green]OK[/] {summary}")


def register(app: typer.Typer) -> None:
    app.command("validate")(validate)
