"""`vge demo` on the bundled sample: replays every run and prints the main table."""

from __future__ import annotations

import json
from pathlib import Path

from vge_analytics.cli import main
from vge_analytics.commands.demo import command_name

LOGS = Path(__file__).resolve().parents[3] / "logs"


def test_demo_replays_the_sample_and_prints_the_table(tmp_path: Path, capsys, monkeypatch) -> None:
    monkeypatch.setenv("COLUMNS", "250")  # a wide terminal: no column is ellipsised
    out = tmp_path / "replayed"
    assert main(["demo", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    run_ids = sorted(p.name for p in (LOGS / "runs").iterdir() if (p / "run.json").is_file())
    assert run_ids, "the bundled sample has runs"
    for run_id in run_ids:
        assert run_id in printed
    for header in ("SR", "SSR", "SPL", "State-F1", "EIR", "TIR", "VSPS", "GVPE", "EER"):
        assert header in printed
    assert f"vge app {out}" in printed
    manifest = json.loads((out / "manifest.json").read_text())
    assert sorted(r["run_id"] for r in manifest["runs"]) == run_ids
    assert all(r["counts"]["quarantined"] == 0 for r in manifest["runs"])
    # A second call reuses everything: same manifest bytes.
    before = (out / "manifest.json").read_bytes()
    assert main(["demo", "--out", str(out)]) == 0
    assert (out / "manifest.json").read_bytes() == before


def test_the_closing_hint_is_a_command_the_shell_runs(tmp_path: Path, monkeypatch) -> None:
    """`vge` when PATH finds the program that runs, else the path it was started by: after
    `.venv/bin/vge demo` in a shell without the venv activated, `.venv/bin/vge app ...`."""
    bin_dir = tmp_path / ".venv" / "bin"
    bin_dir.mkdir(parents=True)
    script = bin_dir / "vge"
    script.write_text("#!/bin/sh\n")
    script.chmod(0o755)
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("PATH", "/usr/bin:/bin")
    assert command_name(".venv/bin/vge") == ".venv/bin/vge"
    assert command_name(str(script)) == str(script)
    monkeypatch.setenv("PATH", f"{bin_dir}:/usr/bin:/bin")  # activated
    assert command_name(".venv/bin/vge") == "vge"
    assert command_name(str(script)) == "vge"
    odd = tmp_path / "my venv" / "bin"
    odd.mkdir(parents=True)
    (odd / "vge").write_text("#!/bin/sh\n")
    assert command_name(str(odd / "vge")) == f"'{odd / 'vge'}'"  # quoted for the shell
    assert command_name("/usr/bin/python3") == "vge"  # `python -m`, a test: the plain name
