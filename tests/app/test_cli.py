"""`vge app` and `vge play`: what they run, and what they say when there is nothing to show."""

from __future__ import annotations

from pathlib import Path

import app
from app import _data, _settings
from vge_analytics import dashboard as dash
from vge_analytics.cli import main
from vge_analytics.commands.app import is_loopback, streamlit_command
from vge_analytics.commands.play import play_command
from vge_analytics.store._limits import SqlLimits

from ..vge_analytics.metrics.metric_files import SR_MULTI


def test_default_out_missing_says_run_vge_demo(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["app"]) == 1
    err = capsys.readouterr().err
    assert err.strip() == (
        "error: No replay output at logs-replayed: run `vge demo` first "
        "(it replays the bundled sample into ./logs-replayed)"
    )


def test_not_a_replay_output(tmp_path, capsys):
    (tmp_path / "steps").mkdir()
    assert main(["app", str(tmp_path)]) == 1
    assert "is not a replay output directory" in capsys.readouterr().err


def test_streamlit_command(tiny_out):
    cmd = streamlit_command(tiny_out, port=8600, headless=True)
    assert cmd[1:4] == ["-m", "vge_analytics.commands._serve", "run"]  # streamlit run, warmed up
    assert Path(cmd[4]) == app.ENTRY_FILE and app.ENTRY_FILE.name == "streamlit_app.py"
    assert cmd[cmd.index("--server.port") + 1] == "8600"
    assert cmd[cmd.index("--server.headless") + 1] == "true"
    assert cmd[cmd.index("--server.address") + 1] == "127.0.0.1"  # this machine only
    assert cmd[-3:] == ["--", "--out", str(tiny_out)]
    limits = SqlLimits.make(memory="1GB", timeout=12.5)
    cmd = streamlit_command(tiny_out, port=1, headless=False, host="0.0.0.0", sql=(limits, 50))
    assert cmd[cmd.index("--server.address") + 1] == "0.0.0.0"
    script_args = cmd[cmd.index("--") + 1 :]
    assert script_args == [
        "--out",
        str(tiny_out),
        "--sql-timeout",
        "12.5",
        "--sql-memory-limit",
        str(1024**3),
        "--sql-max-rows",
        "50",
    ]
    assert _settings.sql_settings(script_args) == (limits, 50)
    default_limits, rows = _settings.sql_settings([])
    assert (default_limits.timeout, rows) == (30.0, 10_000)
    assert default_limits.memory == SqlLimits.make().memory
    # The other pages' analytics queries: `vge app --query-timeout S` passes it on.
    cmd = streamlit_command(tiny_out, port=1, headless=True, query_timeout=7.5)
    script_args = cmd[cmd.index("--") + 1 :]
    assert script_args[-2:] == ["--query-timeout", "7.5"]
    assert _data.query_timeout(script_args) == 7.5
    assert _data.query_timeout(["--query-timeout", "0"]) is None  # no limit
    assert _data.query_timeout([]) == 300.0  # the command line's default


def test_loopback_hosts():
    assert is_loopback("127.0.0.1") and is_loopback("::1") and is_loopback("localhost")
    assert is_loopback("127.8.0.1")
    assert not is_loopback("0.0.0.0") and not is_loopback("192.0.2.2")
    assert not is_loopback("::") and not is_loopback("example.org")


def test_out_argument_precedence(monkeypatch):
    monkeypatch.setenv("VGE_APP_OUT", "/from/env")
    assert _data.out_argument(["--out", "/from/args"]) == "/from/args"
    assert _data.out_argument(["--out=/x"]) == "/x"
    assert _data.out_argument([]) == "/from/env"
    monkeypatch.delenv("VGE_APP_OUT")
    assert _data.out_argument([]) == dash.DEFAULT_OUT


def test_metrics_dir_is_checked_then_passed_on(tiny_out, metrics_folder, tmp_path, capsys):
    cmd = streamlit_command(tiny_out, port=1, headless=True, metrics_dir=metrics_folder)
    assert cmd[-2:] == ["--metrics-dir", str(metrics_folder)]
    assert _data.metrics_dir(cmd[cmd.index("--") + 1 :]) == str(metrics_folder)
    (tmp_path / "x.sql").write_text(SR_MULTI.replace("-- grain: episodes", "-- grain: runs"))
    # A problem in a metric file stops `vge app` with its line, before any server starts.
    assert main(["app", str(tiny_out), "--metrics-dir", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert (
        err == f"error: {tmp_path}/x.sql:6: unknown grain 'runs' (one of: episodes, steps, goals)\n"
    )


def test_metrics_dir_precedence(monkeypatch):
    monkeypatch.setenv("VGE_METRICS_DIR", "/from/env")
    assert _data.metrics_dir(["--metrics-dir", "/from/args"]) == "/from/args"
    assert _data.metrics_dir([]) == "/from/env"
    monkeypatch.setenv("VGE_METRICS_DIR", "")
    assert _data.metrics_dir([]) is None


def test_play_command(tiny_out, tmp_path):
    bench, run = tiny_out.parent / "synth" / "bench", tmp_path / "run"
    cmd = play_command(bench, run, port=8600, headless=True)
    assert cmd[1:4] == ["-m", "vge_analytics.commands._serve", "run"]  # as `vge app` serves
    assert Path(cmd[4]) == app.ENTRY_FILE
    assert cmd[cmd.index("--server.address") + 1] == "127.0.0.1"  # this machine only
    assert cmd[cmd.index("--server.port") + 1] == "8600"
    assert cmd[cmd.index("--") :] == ["--", "--bench", str(bench), "--run", str(run)]
    cmd = play_command(bench, run, port=1, headless=False, host="0.0.0.0", image_width=480)
    assert cmd[cmd.index("--server.address") + 1] == "0.0.0.0"
    script_args = cmd[cmd.index("--") + 1 :]
    assert script_args[-2:] == ["--image-width", "480"]
    assert _settings.play_target(script_args) == _settings.PlayTarget(str(bench), str(run), 480)
    assert _settings.play_target(["--bench", "B"]) == _settings.PlayTarget("B", "human-run", None)
    # `vge app OUT` has no benchmark: the dashboard, without the Play page.
    assert _settings.play_target(["--out", str(tiny_out)]) is None


def test_play_refuses_with_one_line(tiny_out, tmp_path, capsys):
    assert main(["play", str(tmp_path / "nowhere")]) == 1
    err = capsys.readouterr().err
    assert err == f"error: {tmp_path / 'nowhere'}: benchmark directory not found\n"
    vlm = next(p for p in (tiny_out.parent / "synth" / "runs").iterdir() if "vlm" in p.name)
    bench = tiny_out.parent / "synth" / "bench"
    assert main(["play", str(bench), "--out", str(vlm)]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"error: {vlm} is a run of agent kind 'vlm': `vge play` writes human")
    assert err.count("\n") == 1


def test_the_sql_memory_limit_is_sized_from_out(tiny_out, monkeypatch):
    """Without `--sql-memory-limit`, the pages' user SQL (the SQL page, metric files) is
    bounded at 512 MB plus half of OUT's tables (store.sized_memory_limit), passed on to the
    script as bytes; a given limit is passed as given."""
    from vge_analytics.commands import app as app_command
    from vge_analytics.store import table_bytes

    served = []
    monkeypatch.setattr(app_command, "serve", lambda cmd, *a, **k: served.append(cmd))
    assert main(["app", str(tiny_out), "--headless", "--port", "1"]) == 0
    assert (
        main(["app", str(tiny_out), "--headless", "--port", "1", "--sql-memory-limit", "1GB"]) == 0
    )
    expected = 512 * 1024**2 + table_bytes(tiny_out) // 2
    limits = [cmd[cmd.index("--sql-memory-limit") + 1] for cmd in served]
    assert limits == [str(expected), str(1024**3)]
    assert _settings.sql_settings(served[0][served[0].index("--") + 1 :])[0].memory == expected


def test_the_warm_up_opens_the_store_the_pages_use(tiny_out, monkeypatch):
    """The server's warm-up opens OUT within the pages' query bounds (the script arguments
    `vge app` passes): the pages' first data call then finds that store and opens none. A
    store is kept per memory limits, and the pages' (sized from OUT) are not the default's,
    so a warm-up outside them left the first page to open OUT again (0.5 s at 100x)."""
    import sys

    import vge_analytics as va
    from vge_analytics.commands import app as app_command
    from vge_analytics.store import _store, clear_cache

    served = []
    monkeypatch.setattr(app_command, "serve", lambda cmd, *a, **k: served.append(cmd))
    assert main(["app", str(tiny_out), "--headless", "--port", "1"]) == 0
    cmd = served[0]
    monkeypatch.setattr(sys, "argv", [cmd[2], *cmd[3:]])  # as the server's process sees them
    page_memory = int(cmd[cmd.index("--sql-memory-limit") + 1])
    assert page_memory != SqlLimits.make().memory  # the default's store would not do
    opened = []
    real_open = _store._open

    def counted_open(where, limits):
        opened.append(limits.memory)
        return real_open(where, limits)

    monkeypatch.setattr(_store, "_open", counted_open)
    clear_cache()
    try:
        _data.open_as_the_pages_do(str(tiny_out))  # what `app.warm` does last
        assert opened == [page_memory]
        with _data.query_bounds():  # what a page's data call runs within
            va.runs(str(tiny_out))
        assert opened == [page_memory]
    finally:
        clear_cache()
