"""`vge demo`: the main job on the bundled sample, from nothing to the paper's main table.

Builds the sample if it is missing (or reuses it), replays every run into OUT (incremental:
a second call skips unchanged runs), prints the metrics table and says how to open the app.
"""

from __future__ import annotations

import os
import shlex
import shutil
import sys
from pathlib import Path

import typer

from ._output import emit, for_people

_REPO_SAMPLE = Path(__file__).resolve().parents[2] / "logs"


def _bundled_sample() -> Path:
    """The repository's `logs/` when the package runs from a checkout, else `./vge-sample`."""
    from ..synth import BENCH_DIR

    if (_REPO_SAMPLE / BENCH_DIR).is_dir() or (_REPO_SAMPLE.parent / "pyproject.toml").exists():
        return _REPO_SAMPLE
    return Path.cwd() / "vge-sample"


def command_name(argv0: str | None = None) -> str:
    """How the user's shell runs this `vge`: `vge` when that name finds this very program
    on PATH (an activated virtual environment, a user install), else the path it was
    started by (`.venv/bin/vge` after the README's first line without activating)."""
    started = sys.argv[0] if argv0 is None else argv0
    if Path(started).name != "vge" or not Path(started).is_file():
        return "vge"  # not the console script (python -m, a test)
    found = shutil.which("vge")
    if found and os.path.samefile(found, started):
        return "vge"
    return shlex.quote(started if os.sep in started else f".{os.sep}{started}")


def demo(
    out: Path = typer.Option(
        Path("logs-replayed"), "--out", help="Where to write the replay output."
    ),
    sample: Path = typer.Option(
        None, "--sample", help="Sample directory (default: the bundled logs/)."
    ),
    workers: int = typer.Option(1, "--workers", min=1, help="Replay worker processes."),
    force: bool = typer.Option(False, "--force", help="Replay every run again."),
) -> None:
    """Replay the bundled sample (building it first if needed) and print the main table."""
    from rich.console import Console

    from replay import replay_runs
    from replay.io import quarantine_path, run_json_path

    from ..metrics import MetricSet
    from ..metrics import metrics as compute_metrics
    from ..store import DEFAULT_BY
    from ..synth import BENCH_DIR, RUNS_DIR, image_source

    console = Console(highlight=False)
    sample_dir = sample or _bundled_sample()
    bench = sample_dir / BENCH_DIR
    if not bench.is_dir():
        from ..synth import generate

        console.print(
            f"Building the synthetic sample in {sample_dir} (vge synth --scale sample --seed 0) ..."
        )
        generate(sample_dir, scale="sample", seed=0)
    runs = sorted(p for p in (sample_dir / RUNS_DIR).iterdir() if run_json_path(p).is_file())
    console.print(f"Replaying {len(runs)} runs of {sample_dir} into {out} ...")
    manifest = replay_runs(
        runs, bench, out, workers=workers, force=force, image_source=image_source(bench)
    )
    df = compute_metrics(out, by=DEFAULT_BY, metrics_dir=MetricSet.builtin())  # the paper's
    emit(
        for_people(df, DEFAULT_BY),
        "table",
        title="Main results, the paper's metrics: \u2191 higher is better, \u2193 lower is better",
    )
    quarantined = manifest.quarantined
    vge = command_name()
    shown = shlex.quote(str(out))
    console.print(
        f"\nReplay output: {out}  (tables steps, episodes, goals, runs; see docs/REPLAY.md)\n"
        f"Open the dashboard:  {vge} app {shown}\n"
        f'Query it:            {vge} sql {shown} "SELECT model, avg(success::INT) FROM episodes '
        'GROUP BY model"',
        soft_wrap=True,
        markup=False,
    )
    if quarantined:
        console.print(
            f"[yellow]{quarantined} record(s) quarantined: see {quarantine_path(out)}[/]"
        )
        raise typer.Exit(2)


def register(app: typer.Typer) -> None:
    app.command("demo")(demo)
