"""Filters and ids that select nothing, on the bundled sample: each command that takes
`--where`, `--runs` or `--episodes` (or run ids) says so in one line on stderr naming the
value and the nearest OUT holds, and exits 1; a value that matches nothing beside others
that do is a warning (exit 0)."""

from __future__ import annotations

from pathlib import Path

import pytest

from vge_analytics.cli import main

from .test_cli import run

NO_MODEL = (
    "error: --where model=sim-vlm-z selects no row: no model 'sim-vlm-z' "
    "(nearest: sim-vlm-a, sim-vlm-b, sim-vlm-c)\n"
)


@pytest.mark.parametrize(
    ("command", "more"),
    [
        ("metrics", []),
        ("errors", []),
        ("rescore", ["--metrics-dir", str(Path(__file__).parents[3] / "docs/examples/metrics")]),
    ],
)
def test_a_where_that_selects_nothing_is_an_error(capsys, sample_out, command, more) -> None:
    code, out, err = run(capsys, command, str(sample_out), "--where", "model=sim-vlm-z", *more)
    assert (code, out, err) == (1, "", NO_MODEL)


def test_the_line_says_why(capsys, sample_out) -> None:
    out = str(sample_out)
    # `Kettel` is most like a part of `ElectricKettle`; no category is like `Xyz`.
    assert run(capsys, "metrics", out, "--where", "category=Kettel")[2] == (
        "error: --where category=Kettel selects no row: no category 'Kettel' "
        "(nearest: ElectricKettle)\n"
    )
    assert run(capsys, "errors", out, "--where", "category=Xyz")[2] == (
        "error: --where category=Xyz selects no row: no category 'Xyz' (26 values, none alike)\n"
    )
    # A value that is no number matches no number; few values are listed whole.
    assert run(capsys, "metrics", out, "--where", "n_goals=two", "--metrics", "SR")[2] == (
        "error: --where n_goals=two selects no row: no n_goals 'two' (values: 1, 2, 3, 4)\n"
    )
    # Each value is there, but no row has both: sim-vlm-a kept its whole history.
    code, _, err = run(
        capsys, "metrics", out, "--where", "model=sim-vlm-a", "--where", "meta_history_length=3"
    )
    assert (code, err) == (
        1,
        "error: --where model=sim-vlm-a --where meta_history_length=3 selects no row: each "
        "value is there, but no row has them all\n",
    )
    # A step column, for a step metric.
    code, _, err = run(capsys, "metrics", out, "--where", "action_type=rotat", "--metrics", "EIR")
    assert (code, err) == (
        1,
        "error: --where action_type=rotat selects no row: no action_type 'rotat' "
        "(nearest: rotate)\n",
    )


def test_a_value_that_matches_nothing_beside_others_is_a_warning(capsys, sample_out) -> None:
    code, out, err = run(
        capsys, "metrics", str(sample_out), "--where", "run_id=sim-vlm-a,sim-vlm-x",
        "--metrics", "SR", "-f", "csv",
    )  # fmt: skip
    assert code == 0 and out.splitlines()[1].startswith("sim-vlm-a,")
    assert err == (
        "warning: --where run_id=sim-vlm-a,sim-vlm-x: no run_id 'sim-vlm-x' (nearest: "
        "sim-vlm-a, sim-vlm-b, sim-vlm-c) (the other values select rows)\n"
    )
    assert run(capsys, "metrics", str(sample_out), "--where", "model=sim-vlm-a")[2] == ""


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (
            ["compare", "{out}", "sim-hman", "sim-vlm-f"],
            "unknown run 'sim-hman' in {out}; nearest: sim-human, sim-vlm-a",
        ),
        (
            ["diff", "{out}", "sim-human", "sim-vlm-f-hist"],
            "unknown run 'sim-vlm-f-hist' in {out}; nearest: sim-vlm-f-hist0, sim-vlm-f-hist3, "
            "sim-vlm-f",
        ),
        (
            ["diff", "{out}", "sim-human", "sim-vlm-f", "--episodes", "CarKey_000-1"],
            "not replayed in both 'sim-human' and 'sim-vlm-f': episode 'CarKey_000-1'; "
            "nearest: CarKey_000-01, CarKey_000-02, CarKey_000-03",
        ),
        (
            ["sweep", "{out}", "--runs", "sim-vlm-q"],
            "unknown run 'sim-vlm-q' in {out}; nearest: sim-vlm-a, sim-vlm-b, sim-vlm-c",
        ),
        (
            ["export", "{out}", "-f", "atif", "--out", "{dest}", "--runs", "sim-vlm-q"],
            "unknown run(s) 'sim-vlm-q' in {out}; nearest: sim-vlm-a, sim-vlm-b, sim-vlm-c",
        ),
        (
            ["export", "{out}", "-f", "atif", "--out", "{dest}", "--episodes", "CarKey_000-1"],
            "unknown episode(s) 'CarKey_000-1' in the selected runs of {out}; nearest: "
            "CarKey_000-01, CarKey_000-00, CarKey_000-02",
        ),
    ],
)
def test_ids_that_are_not_there_get_the_nearest(capsys, sample_out, tmp_path, args, message):
    fill = {"out": str(sample_out), "dest": str(tmp_path / "dest")}
    code = main([a.format(**fill) for a in args])
    assert (code, capsys.readouterr().err) == (1, f"error: {message.format(**fill)}\n")
    assert not (tmp_path / "dest").exists()


def test_run_episodes_that_are_not_tasks_get_the_nearest(capsys, tmp_path) -> None:
    bench = Path(__file__).parents[3] / "logs" / "bench"
    code = main(
        ["run", str(bench), "--agent", "sim:f", "--episodes", "Lamp_000-1", "--out", str(tmp_path / "r")]
    )
    err = capsys.readouterr().err
    assert code == 1
    assert err == (
        f"error: --episodes: not in {bench}/tasks.jsonl: 'Lamp_000-1'; nearest: Lamp_000-01, "
        "Lamp_000-00, Lamp_000-02\n"
    )
