"""`vge play BENCH [--out RUN_DIR]`: the Play page, where a person plays the benchmark.

Creates (or opens) the human run RUN_DIR, then runs the Streamlit app as `vge app` does
(`streamlit run app/streamlit_app.py -- --bench BENCH --run RUN_DIR`, through
`vge_analytics.commands._serve`); with a benchmark the app shows the Play page alone.

The server listens on 127.0.0.1 (this machine only) unless `--host` says otherwise: whoever
reaches the page plays into RUN_DIR, so opening it to the network is a choice this command
warns about.
"""

from __future__ import annotations

import os
from pathlib import Path

import typer

from vge_analytics import play
from vge_analytics.commands.app import (
    LOOPBACK,
    headless_option,
    host_option,
    is_loopback,
    port_option,
    serve,
    streamlit_command,
)
from vge_analytics.dashboard import OUT_ENV


def play_command(
    bench: Path,
    run: Path,
    *,
    port: int,
    headless: bool,
    host: str = LOOPBACK,
    image_width: int | None = None,
) -> list[str]:
    """The argument list that serves the Play page for BENCH and RUN on `host:port`: the
    dashboard's server command, with the Play page's script arguments."""
    cmd = streamlit_command(run, port=port, headless=headless, host=host)
    script = ["--bench", str(bench), "--run", str(run)]
    if image_width is not None:
        script += ["--image-width", str(image_width)]
    return [*cmd[: cmd.index("--")], "--", *script]


def play_cmd(
    bench: Path = typer.Argument(..., help="Benchmark directory (ssm/, tasks.jsonl)."),
    out: Path = typer.Option(
        Path(play.DEFAULT_RUN_DIR),
        "--out",
        help="Run directory to write (created if missing; an existing human run goes on).",
    ),
    run_id: str = typer.Option(
        None, "--run-id", help="run_id of a new run (default: the directory's name)."
    ),
    model: str = typer.Option(
        None, "--model", help="model of a new run: the participant or group (default: human)."
    ),
    lam: float = typer.Option(
        None, "--lambda", help="λ of a new run (default: each task's, else 5)."
    ),
    image_width: int = typer.Option(
        None,
        "--image-width",
        min=100,
        help="Show the view this many pixels wide (default: as wide as its column).",
    ),
    port: int = port_option(),
    host: str = host_option("lets anyone on the network play into the run"),
    headless: bool = headless_option(),
) -> None:
    """Play the benchmark in the browser, writing a human run that `vge replay` reads.

    Pick an episode, click on the device's views; each step is written to the run as it is
    played.
    """
    run = play.HumanRun.open(out, bench, run_id=run_id, model=model, lam=lam)
    bench_dir, run_dir = bench.resolve(), run.root.resolve()
    cmd = play_command(
        bench_dir, run_dir, port=port, headless=headless, host=host, image_width=image_width
    )
    env = dict(os.environ)
    env.pop(OUT_ENV, None)  # nothing for `_serve` to warm up: no replay output here
    shown = "localhost" if is_loopback(host) else host
    statuses = run.statuses()
    played = sum(s.state == "finished" for s in statuses)
    typer.echo(
        f"Playing {bench_dir} into {run_dir} ({played} of {len(statuses)} episodes played) on "
        f"http://{shown}:{port} (Ctrl-C stops it)",
        err=True,
    )
    serve(cmd, env, host=host, port=port, exposes=f"can play and write steps into {run_dir}")


def register(typer_app: typer.Typer) -> None:
    typer_app.command("play")(play_cmd)
