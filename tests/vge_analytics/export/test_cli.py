"""`vge export` on the command line: what it writes and says, and bad input in one line with
exit code 1."""

from __future__ import annotations

import sys

import pytest

from vge_analytics.cli import main


def _run(capsys, *args: str) -> tuple[int, str, str]:
    code = main(["export", *args])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_writes_and_says_where(hand_out, tmp_path, capsys):
    code, out, err = _run(
        capsys, str(hand_out), "--format", "atif", "--out", str(tmp_path), "--runs", "oven-human"
    )
    assert code == 0
    assert sorted(p.name for p in (tmp_path / "oven-human").iterdir()) == [
        f"hw_dash_{c}.json" for c in "abcde"
    ]
    lines = err.strip().splitlines()
    assert len(lines) == 2  # not a terminal: no progress bar, a line per run
    assert lines[0].startswith("exported oven-human: 5 episodes in ")
    assert lines[0].endswith(" s (5 of 5)")
    assert lines[1].startswith(
        f"wrote 5 trajectories (1 run(s), 5 episodes, 32 steps) to {tmp_path} in "
    )
    code, out, err = _run(
        capsys, str(hand_out), "-f", "inspect", "--out", str(tmp_path), "--images", "none"
    )
    lines = err.strip().splitlines()
    assert [line.split(" in ")[0] for line in lines[:2]] == [
        "exported kettle-vlm: 7 episodes",
        "exported oven-human: 5 episodes",
    ]
    assert [line.split(" s ")[-1] for line in lines[:2]] == ["(7 of 12)", "(12 of 12)"]
    code, out, err = _run(
        capsys, str(hand_out), "-f", "inspect", "--out", str(tmp_path), "--no-progress"
    )
    assert not err.startswith("exported")
    code, out, err = _run(
        capsys, str(hand_out), "-f", "inspect", "--out", str(tmp_path), "--episodes", "hw_dash_e"
    )
    assert code == 0
    assert (tmp_path / "oven-human.eval").is_file()
    assert err.strip().splitlines()[-1] == f"open them:  inspect view --log-dir {tmp_path}"


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (
            ["--runs", "nope,kettle-vlm"],
            "error: unknown run(s) 'nope' in {out}; runs: kettle-vlm, oven-human",
        ),
        (
            ["--episodes", "hw_dash_a,nope"],
            "error: unknown episode(s) 'nope' in the selected runs of {out}; 12 episodes, "
            "none alike",
        ),
        (
            ["--runs", "kettle-vlm", "--episodes", "hw_dash_a"],
            "error: unknown episode(s) 'hw_dash_a' in the selected runs of {out}; episodes: "
            "hw_kettle_a, hw_kettle_b, hw_kettle_c, hw_kettle_d, hw_kettle_e, hw_kettle_f, "
            "hw_kettle_g",
        ),
        (["--images", "some"], "error: --images must be one of embed, none, not 'some'"),
        (["--format", "html"], "error: --format must be one of inspect, atif, not 'html'"),
    ],
)
def test_bad_selection_one_line(hand_out, tmp_path, capsys, args, message):
    dest = tmp_path / "dest"
    base = [str(hand_out), "--out", str(dest)]
    if "--format" not in args:
        base += ["--format", "atif"]
    code, out, err = _run(capsys, *base, *args)
    assert (code, out, err) == (1, "", message.format(out=hand_out) + "\n")
    assert not dest.exists()


def test_out_without_manifest(hand_out, tmp_path, capsys):
    for name in ("steps", "episodes", "goals"):
        (tmp_path / "out" / name).mkdir(parents=True)
    code, out, err = _run(
        capsys, str(tmp_path / "out"), "-f", "inspect", "--out", str(tmp_path / "d")
    )
    assert code == 1
    assert err == (
        f"error: {tmp_path / 'out'}: no manifest.json, not a replay output directory; run "
        f"`vge replay RUN... --bench BENCH --out {tmp_path / 'out'}` first\n"
    )
    code, out, err = _run(
        capsys, str(tmp_path / "none"), "-f", "atif", "--out", str(tmp_path / "d")
    )
    assert (code, len(err.splitlines())) == (1, 1)
    assert "no manifest.json" in err


@pytest.mark.parametrize(("fmt", "package"), [("inspect", "inspect_ai"), ("atif", "atif")])
def test_without_the_export_extra(hand_out, tmp_path, capsys, monkeypatch, fmt, package):
    monkeypatch.setitem(sys.modules, package, None)  # `import` raises ImportError
    code, out, err = _run(capsys, str(hand_out), "-f", fmt, "--out", str(tmp_path))
    assert (code, out) == (1, "")
    assert (
        err
        == f"error: --format {fmt} needs the {package} package: pip install 'vge-analytics[export]'\n"
    )
