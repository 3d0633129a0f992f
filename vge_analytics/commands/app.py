"""`vge app [OUT]`: the Streamlit dashboard over a replay output directory.

Runs `streamlit run app/streamlit_app.py -- --out OUT` with the same Python (through
`vge_analytics._serve`, which warms the libraries and OUT up first). The app reads
OUT from `--out` (and from the `VGE_APP_OUT` environment variable, which this command also
sets), so it can be started by hand with either.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import typer

from vge_analytics.dashboard import DEFAULT_OUT, OUT_ENV, app_script, check_out


def streamlit_command(
    out: Path, *, port: int, headless: bool, address: str | None = None
) -> list[str]:
    """The argument list that serves the dashboard for OUT: `streamlit run ...` through
    `vge_analytics._serve`, which warms the libraries and OUT up before the server listens."""
    cmd = [
        sys.executable,
        "-m",
        "vge_analytics._serve",
        "run",
        str(app_script()),
        "--server.port",
        str(port),
        "--server.headless",
        "true" if headless else "false",
        "--server.fileWatcherType",
        "none",
        "--browser.gatherUsageStats",
        "false",
        "--client.toolbarMode",
        "minimal",
    ]
    if address is not None:
        cmd += ["--server.address", address]
    return [*cmd, "--", "--out", str(out)]


def app(
    out: Path = typer.Argument(
        Path(DEFAULT_OUT),
        help="Replay output directory (default: ./logs-replayed, written by `vge demo`).",
    ),
    port: int = typer.Option(8501, "--port", help="Port to serve on."),
    headless: bool = typer.Option(
        False, "--headless", help="Do not open a browser (servers, CI, tests)."
    ),
    address: str = typer.Option(
        None, "--address", help="Address to listen on (default: Streamlit's, all interfaces)."
    ),
) -> None:
    """Open the dashboard: leaderboard, errors, navigation, grounding, budgets, human vs VLM,
    episode viewer and SQL over a replay output directory."""
    resolved = check_out(out)
    cmd = streamlit_command(resolved, port=port, headless=headless, address=address)
    env = {**os.environ, OUT_ENV: str(resolved)}
    typer.echo(f"Dashboard for {resolved} on http://localhost:{port} (Ctrl-C stops it)", err=True)
    sys.stderr.flush()
    if os.name == "posix":
        # Replace this process: signals (Ctrl-C, kill) go straight to Streamlit.
        os.execve(sys.executable, cmd, env)
    raise typer.Exit(subprocess.call(cmd, env=env))  # pragma: no cover - not POSIX


def register(typer_app: typer.Typer) -> None:
    typer_app.command("app")(app)
