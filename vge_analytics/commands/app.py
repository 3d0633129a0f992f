"""`vge app [OUT]`: the Streamlit dashboard over a replay output directory.

Runs `streamlit run app/streamlit_app.py -- --out OUT` with the same Python (through
`vge_analytics.commands._serve`, which warms the libraries and OUT up first). The app reads
OUT from `--out` (and from the `VGE_APP_OUT` environment variable, which this command also
sets), so it can be started by hand with either. `--metrics-dir DIR` is checked here (a
problem in a metric file stops the command with its line) and passed on as `--metrics-dir`:
every page then shows the folder's metrics.

The server listens on 127.0.0.1 (this machine only) unless `--host` says otherwise: the
dashboard shows the logs and the model outputs, and its SQL page runs queries, so opening it
to the network is a choice this command warns about.
"""

from __future__ import annotations

import ipaddress
import os
import subprocess
import sys
from pathlib import Path

import typer

import app as dashboard_app
from vge_analytics.dashboard import DEFAULT_OUT, OUT_ENV
from vge_analytics.metrics import load_metrics
from vge_analytics.store import (
    APP_MAX_ROWS,
    APP_TIMEOUT,
    CLI_TIMEOUT,
    SLOT_WAIT,
    SqlLimits,
    default_max_queries,
    format_size,
    sized_memory_limit,
)

from ._options import memory_limit_option, metrics_dir_option

LOOPBACK = "127.0.0.1"


def port_option() -> int:
    """`--port` of the commands that serve the app (a typer option default)."""
    return typer.Option(8501, "--port", help="Port to serve on.")


def host_option(opened: str) -> str:
    """`--host`/`--address`: this machine only by default; `opened` says what listening on
    0.0.0.0 lets the network do (a typer option default)."""
    return typer.Option(
        LOOPBACK,
        "--host",
        "--address",
        help=f"Address to listen on. The default serves this machine only; 0.0.0.0 {opened}.",
    )


def headless_option() -> bool:
    """`--headless` (a typer option default)."""
    return typer.Option(False, "--headless", help="Do not open a browser (servers, CI, tests).")


def is_loopback(host: str) -> bool:
    """True when `host` is reachable from this machine only (127.0.0.0/8, ::1, localhost)."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def serve(cmd: list[str], env: dict[str, str], *, host: str, port: int, exposes: str) -> None:
    """Become the server `cmd` starts (`vge app`, `vge play`), after a warning when it
    listens beyond this machine: anyone who can reach the port then `exposes` (what they
    can do there)."""
    if not is_loopback(host):
        typer.echo(
            f"warning: listening on {host}: anyone who can reach this machine on port {port} "
            f"{exposes}",
            err=True,
        )
    sys.stderr.flush()
    if os.name == "posix":
        # Replace this process: signals (Ctrl-C, kill) go straight to Streamlit.
        os.execve(sys.executable, cmd, env)
    raise typer.Exit(subprocess.call(cmd, env=env))  # pragma: no cover - not POSIX


def streamlit_command(
    out: Path,
    *,
    port: int,
    headless: bool,
    host: str = LOOPBACK,
    sql: tuple[SqlLimits, int] | None = None,
    metrics_dir: Path | None = None,
    query_timeout: float | None = None,
    max_queries: int | None = None,
) -> list[str]:
    """The argument list that serves the dashboard for OUT on `host:port`: `streamlit run
    ...` through `vge_analytics.commands._serve`, which warms the libraries and OUT up before the
    server listens. `sql`: the SQL page's limits and row cap, `metrics_dir`: the metrics
    folder, `query_timeout`: the pages' analytics queries' time limit, `max_queries`: how many
    SQL page queries run at once, passed on to the app."""
    cmd = [
        sys.executable,
        "-m",
        "vge_analytics.commands._serve",
        "run",
        str(dashboard_app.ENTRY_FILE),
        "--server.address",
        host,
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
        "--",
        "--out",
        str(out),
    ]
    if sql is not None:
        limits, rows = sql
        cmd += [
            "--sql-timeout",
            f"{limits.timeout or 0:g}",
            "--sql-memory-limit",
            str(limits.memory),
            "--sql-max-rows",
            str(rows),
        ]
    if metrics_dir is not None:
        cmd += ["--metrics-dir", str(metrics_dir)]
    if query_timeout is not None:
        cmd += ["--query-timeout", f"{query_timeout:g}"]
    if max_queries is not None:
        cmd += ["--sql-max-queries", str(max_queries)]
    return cmd


def app_command(
    out: str = typer.Argument(
        DEFAULT_OUT,
        help="Replay output directory (default: ./logs-replayed, written by `vge demo`).",
    ),
    port: int = port_option(),
    host: str = host_option(
        "opens the dashboard (logs, model outputs, the SQL page) to the network"
    ),
    headless: bool = headless_option(),
    sql_timeout: float = typer.Option(
        APP_TIMEOUT, "--sql-timeout", help="The SQL page stops a query after this many seconds."
    ),
    sql_memory_limit: str = memory_limit_option(
        "--sql-memory-limit", "a query of the SQL page, or of a metric file on any page"
    ),
    sql_max_rows: int = typer.Option(
        APP_MAX_ROWS, "--sql-max-rows", min=1, help="Rows the SQL page shows and downloads."
    ),
    sql_max_queries: int = typer.Option(
        None,
        "--sql-max-queries",
        min=1,
        help="SQL page queries that run at once, for all visitors; another waits up to "
        f"{SLOT_WAIT:g} s, then is refused (default: as many as fit in this machine's memory "
        "at --sql-memory-limit and half again).",
    ),
    query_timeout: float = typer.Option(
        CLI_TIMEOUT,
        "--query-timeout",
        min=0.0,
        help="The other pages stop an analytics query (a metric, a table) after this many "
        "seconds, with one line (0: no limit).",
    ),
    metrics_dir: str = metrics_dir_option(
        "A folder of metric files whose metrics every page shows (overriding or adding to the "
        "built-in ones); the Rescore page shows what they change."
    ),
) -> None:
    """Open the dashboard over a replay output directory in the browser.

    Its pages: leaderboard, errors, navigation, grounding, budgets, human vs VLM,
    significance, side by side, rescore, episode viewer and SQL.
    """
    from vge_analytics.dashboard import check_out

    resolved = check_out(out)
    folder = None
    if metrics_dir:
        load_metrics(metrics_dir)  # every problem of its files, before the server starts
        folder = Path(metrics_dir).resolve()
    memory = sized_memory_limit(resolved, sql_memory_limit)
    limits = SqlLimits.make(memory=memory, timeout=sql_timeout)
    max_queries = sql_max_queries or default_max_queries(limits)
    cmd = streamlit_command(
        resolved,
        port=port,
        headless=headless,
        host=host,
        sql=(limits, sql_max_rows),
        metrics_dir=folder,
        query_timeout=query_timeout,
        max_queries=max_queries,
    )
    env = {**os.environ, OUT_ENV: str(resolved)}
    shown = "localhost" if is_loopback(host) else host
    typer.echo(
        f"Dashboard for {resolved} on http://{shown}:{port} (Ctrl-C stops it); SQL page "
        f"queries stop after {limits.timeout or 0:g} s or {format_size(limits.memory)}, "
        f"{max_queries} at most at once",
        err=True,
    )
    serve(
        cmd,
        env,
        host=host,
        port=port,
        exposes="can read the logs and model outputs and run queries on the SQL page",
    )


def register(typer_app: typer.Typer) -> None:
    typer_app.command("app")(app_command)
