"""`vge demo` on the bundled sample: replays every run and prints the main table."""

from __future__ import annotations

import json
from pathlib import Path

from vge_analytics.cli import main

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
