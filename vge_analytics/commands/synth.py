"""`vge synth --out DIR [--scale tiny|sample|full] [--seed N] [--images] [--seeds N]
[--device-spread S] [--runs ID,...]`: the synthetic benchmark and its simulated runs
(docs/SYNTHETIC.md)."""

from __future__ import annotations

import time
from pathlib import Path

import typer

from replay import ConfigError


def synth(
    out: Path = typer.Option(..., "--out", help="Output directory (bench/ and runs/ go there)."),
    scale: str = typer.Option("sample", "--scale", help="tiny, sample or full."),
    seed: int = typer.Option(0, "--seed", help="Seed of every random choice."),
    images: bool = typer.Option(
        False, "--images", help="Also render every view into bench/images/."
    ),
    workers: int = typer.Option(
        0, "--workers", help="Processes (0: one per CPU); output does not depend on it."
    ),
    agent_seeds: int = typer.Option(
        1,
        "--seeds",
        min=1,
        help="Play each run N times with other random choices (runs <run_id>-seed<k>, "
        "meta.seed = k): repeated runs for `vge passk`.",
    ),
    device_spread: float = typer.Option(
        0.0,
        "--device-spread",
        help="How much devices differ in difficulty, in logits (0: as their logic makes them; "
        "1 is strong): a device hard for one profile is hard for all.",
    ),
    only_runs: str | None = typer.Option(
        None, "--runs", metavar="ID,...", help="Only these simulated runs (default: all)."
    ),
) -> None:
    """Generate a synthetic VGEBench-style benchmark and simulated agent runs."""
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    from vge_analytics.synth import SCALES, SynthError, generate

    if scale not in SCALES:
        raise ConfigError(f"--scale must be one of {', '.join(SCALES)}, not {scale!r}")
    console = Console(stderr=True)
    started = time.perf_counter()
    with Progress(
        TextColumn("[bold]synth[/] {task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=console,
        transient=False,
    ) as progress:
        task = progress.add_task(f"{scale} devices", total=None)

        def tick(done: int, total: int) -> None:
            progress.update(task, completed=done, total=total)

        try:
            summary = generate(
                out,
                scale=scale,
                seed=seed,
                workers=workers or None,
                images=images,
                progress=tick,
                agent_seeds=agent_seeds,
                device_spread=device_spread,
                only_runs=[r.strip() for r in only_runs.split(",") if r.strip()]
                if only_runs is not None
                else None,
            )
        except SynthError as exc:
            raise ConfigError(str(exc)) from None
    stats = summary.statistics
    elapsed = time.perf_counter() - started
    console.print(
        f"[bold green]OK[/] {out}: {stats.get('devices', 0)} devices in "
        f"{len(summary.categories)} categories, {stats.get('episodes', 0)} episodes "
        f"({stats.get('single_turn', 0)} single / {stats.get('multi_turn', 0)} multi-turn), "
        f"{len(summary.runs)} runs, in {elapsed:.1f}s"
    )


def register(app: typer.Typer) -> None:
    app.command("synth")(synth)
