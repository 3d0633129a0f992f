"""The commands: formats (json list of objects with the paper's metric names, latex marks), exit codes and
one-line errors."""

from __future__ import annotations

import inspect
import json
from pathlib import Path

import pytest

from vge_analytics.cli import main

PAPER_METRICS = ["SR", "SSR", "SPL", "State-F1", "EIR", "TIR", "VSPS", "GVPE", "EER", "PSR",
         "AvgDist", "AvgWDist"]  # fmt: skip


def run(capsys, *args: str) -> tuple[int, str, str]:
    code = main([*args])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_metrics_json(capsys, hand_out: Path) -> None:
    code, out, _ = run(capsys, "metrics", str(hand_out), "--format", "json")
    assert code == 0
    rows = json.loads(out)
    assert isinstance(rows, list) and len(rows) == 2
    for row in rows:
        assert list(row) == ["run_id", "model", *PAPER_METRICS]
    assert rows[0]["SR"] == 100 * 4 / 7  # full precision


def test_metrics_latex_marks(capsys, hand_out: Path) -> None:
    # Three groups (n_goals 1, 2, 3) so that both best and second best are marked.
    code, out, _ = run(
        capsys, "metrics", str(hand_out), "--by", "n_goals", "--metrics", "SR,SSR,VSPS",
        "--format", "latex",
    )  # fmt: skip
    assert code == 0
    assert "\\textbf{" in out and "\\underline{" in out
    assert "SR $\\uparrow$" in out and "VSPS $\\downarrow$" in out
    assert "\\toprule" in out and "\\bottomrule" in out
    # SR by n_goals: 1 goal 75.00, 2 goals 71.43, 3 goals 100.00 -> 100 bold, 75 underlined
    assert "\\textbf{100.00}" in out and "\\underline{75.00}" in out
    # VSPS is lower-better: 3 goals has 0.00 (kettle c), the best
    assert "\\textbf{0.00}" in out


def test_metrics_latex_table2_shape(capsys, hand_out: Path) -> None:
    code, out, _ = run(capsys, "metrics", str(hand_out), "--format", "latex")
    assert code == 0
    assert "\\multicolumn{2}{c}{Task Performance}" in out
    assert "\\multicolumn{4}{c}{Visual Grounding and Perception}" in out
    assert "Model &" in out and "model-k" in out and "kettle-vlm" not in out


def test_metrics_main_table(capsys, hand_out: Path) -> None:
    code, out, _ = run(capsys, "metrics", str(hand_out), "--metrics", "main", "-f", "json")
    assert code == 0 and list(json.loads(out)[0]) == ["run_id", "model", *PAPER_METRICS[:9]]


def test_metrics_markdown_and_csv(capsys, hand_out: Path) -> None:
    code, out, _ = run(capsys, "metrics", str(hand_out), "--by", "n_goals", "-f", "markdown")
    assert code == 0
    assert "| n_goals | SR \u2191 |" in out and "**100.00**" in out and "<u>75.00</u>" in out
    code, out, _ = run(capsys, "metrics", str(hand_out), "-f", "csv")
    assert out.splitlines()[0] == ",".join(["run_id", "model", *PAPER_METRICS])
    code, out, _ = run(capsys, "metrics", str(hand_out))
    assert code == 0 and "SR \u2191" in out and "VSPS \u2193" in out


def test_metrics_errors_are_one_line(capsys, hand_out: Path) -> None:
    code, out, err = run(capsys, "metrics", str(hand_out), "--metrics", "XX")
    assert code == 1 and err.count("\n") == 1 and "unknown metric 'XX'" in err
    code, _, err = run(capsys, "metrics", str(hand_out), "--format", "yaml")
    assert code == 1 and "unknown format" in err
    code, _, err = run(capsys, "metrics", str(hand_out / "nope"))
    assert code == 1 and "not found" in err and "Traceback" not in err


def test_errors_command(capsys, hand_out: Path) -> None:
    code, out, _ = run(capsys, "errors", str(hand_out), "-f", "json")
    assert code == 0
    doc = json.loads(out)
    assert set(doc) == {"error_types", "error_groups", "switch_classes"}
    assert all(isinstance(v, list) for v in doc.values())
    kettle = [r for r in doc["error_types"] if r["run_id"] == "kettle-vlm"]
    assert [r["count"] for r in kettle] == [4, 4, 4, 5, 2, 0, 1]
    code, out, _ = run(capsys, "errors", str(hand_out))
    assert code == 0 and "Invalid Coord Error" in out and "NP" in out


def test_compare_command(capsys, pair_out: Path) -> None:
    code, out, _ = run(
        capsys, "compare", str(pair_out), "A", "B", "--resamples", "200", "-f", "json"
    )
    assert code == 0
    doc = json.loads(out)
    assert set(doc) == {"summary", "metrics", "mcnemar", "errors", "flips"}
    assert doc["mcnemar"][0]["p_value"] == 0.21875
    code, out, _ = run(capsys, "compare", str(pair_out), "A", "B", "--resamples", "50")
    assert code == 0 and "p_value" in out
    code, _, err = run(capsys, "compare", str(pair_out), "A", "Z")
    assert code == 1 and "unknown run 'Z'" in err


def test_sweep_and_sql_commands(capsys, hand_out: Path) -> None:
    code, out, _ = run(capsys, "sweep", str(hand_out), "--lambdas", "2,3", "-f", "json")
    assert code == 0
    rows = json.loads(out)
    assert [(r["run_id"], r["lambda"]) for r in rows] == [
        ("kettle-vlm", 2.0), ("kettle-vlm", 3.0), ("oven-human", 2.0), ("oven-human", 3.0),
    ]  # fmt: skip
    code, out, _ = run(
        capsys, "sql", str(hand_out), "SELECT count(*) AS n FROM goals", "-f", "json"
    )
    assert code == 0 and json.loads(out) == [{"n": 21}]
    code, _, err = run(capsys, "sql", str(hand_out), "DROP VIEW steps")
    assert code == 1 and "read-only" in err
    code, _, err = run(capsys, "sql", str(hand_out), "SELECT * FROM read_csv('/etc/passwd')")
    assert code == 1 and "outside" in err


@pytest.mark.parametrize("fmt", ["table", "json", "csv", "markdown", "latex"])
def test_every_format_everywhere(capsys, hand_out: Path, pair_out: Path, fmt: str) -> None:
    # Each command prints a value known by hand, in the format's own way: two decimals where
    # a person reads the table, every digit where a program reads the data.
    for args, value in (
        (("metrics", str(hand_out)), 100 * 4 / 7),  # kettle SR: 4 of 7
        (("errors", str(hand_out)), 37.5),  # oven action_error: 6 of its 16 errors
        (("compare", str(pair_out), "A", "B", "--resamples", "20"), 60.0),  # B's SR: 6 of 10
        # Kettle SR at λ 3: c (its own λ is 2), f (B_global 6, success at its 5th step) and g
        # (one step) succeed; a and d run out of B_local, b hits its budget, e's log ends.
        (("sweep", str(hand_out), "--lambdas", "3"), 100 * 3 / 7),
        (("sql", str(hand_out), "SELECT run_id, model FROM runs"), "model-o"),
    ):
        code, out, err = run(capsys, *args, "--format", fmt)
        assert code == 0, (args, err)
        if isinstance(value, float):
            value = f"{value:.2f}" if fmt in ("table", "markdown", "latex") else repr(value)
        assert value in out, (args[0], value)


def test_help_names_each_command_in_a_whole_sentence(capsys, monkeypatch) -> None:
    """`vge --help` gives each command the first paragraph of its docstring on one line:
    a whole sentence, never one cut at the docstring's line break."""
    from vge_analytics.cli import _register_all, app, one_line

    monkeypatch.setenv("COLUMNS", "250")  # wide enough that rich does not wrap a line
    code, out, _ = run(capsys, "--help")
    assert code == 0
    _register_all()
    for info in app.registered_commands:
        first = inspect.cleandoc(info.callback.__doc__).split("\n\n")[0]
        assert info.short_help == one_line(info.callback.__doc__) == " ".join(first.split())
        assert info.short_help.endswith("."), info.name
        line = next(x for x in out.splitlines() if x.startswith(f"│ {info.name} "))
        assert info.short_help in line, (info.name, line)
    assert one_line("Open it\n    in the browser.\n\n    More.") == "Open it in the browser."
    assert one_line(None) == ""


@pytest.mark.parametrize(
    ("args", "suggested"),
    [
        (["metrics", "OUT", "--metric", "SR"], "(Possible options: --metrics, --metrics-dir)"),
        (["replay", "RUN", "--mcap-episode", "e1"], "(Possible options: --mcap, --mcap-episodes)"),
        (["errors", "OUT", "--formt", "json"], "(Possible options: --format)"),
    ],
)
def test_a_near_miss_option_gets_a_suggestion(capsys, args, suggested) -> None:
    code, out, err = run(capsys, *args)
    assert code == 2 and out == ""  # click's usage error, not a crash
    assert f"Error: No such option: {args[2]} {suggested}" in err
    assert f"{args[0]} --help' for help." in err  # the program's name is pytest's here


def test_mcap_episodes_that_name_no_episode(capsys, tmp_path: Path) -> None:
    """`vge replay --mcap-episodes` with a typo: one line naming the nearest episodes, exit 1
    before anything is written when no id is an episode; a warning when some are."""
    root = Path(__file__).resolve().parents[3]
    bench, run_dir = str(root / "logs" / "bench"), str(root / "logs" / "runs" / "sim-vlm-a")
    out = tmp_path / "out"
    args = ["replay", run_dir, "--bench", bench, "--out", str(out), "--no-progress"]
    code, _, err = run(capsys, *args, "--mcap-episodes", "CarKey_000-1")
    assert code == 1 and not out.exists()
    assert err == (
        f"error: --mcap-episodes selects no episode (no MCAP file): not an episode of "
        f"{bench}/tasks.jsonl: 'CarKey_000-1'; nearest: CarKey_000-01, CarKey_000-00, "
        "CarKey_000-02\n"
    )
    code, _, err = run(capsys, *args, "--mcap-episodes", "CarKey_000-1,CarKey_000-01")
    assert code == 0
    assert err.startswith("warning: --mcap-episodes: not an episode of ")
    assert [p.name for p in out.rglob("*.mcap")] == ["CarKey_000-01.mcap"]


def test_a_command_run_alone_prints_what_the_whole_app_prints(capsys, monkeypatch) -> None:
    """`main` runs a command in an app that holds it alone (`cli._app_for`): its help, its
    usage errors and a mistyped name read as they do from the app of every command."""
    from vge_analytics import cli

    cli._register_all()
    names = [info.name for info in cli.app.registered_commands]
    assert [c.name for c in cli._app_for(["--debug", "metrics", "x"]).registered_commands] == [
        "metrics"
    ]
    for whole in (["metrcs"], ["--help"], ["--help", "metrics"], ["--debug", "--help", "sql"]):
        assert cli._app_for(whole) is cli.app
    usage = (["metrics", "--no-such"], ["metrics"], ["--help", "metrics"], ["metrcs"])
    for args in (*([name, "--help"] for name in names), *usage):
        alone = run(capsys, *args)
        with monkeypatch.context() as patched:
            patched.setattr(cli, "_app_for", lambda args: cli.app)
            assert run(capsys, *args) == alone, args
