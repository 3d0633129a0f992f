"""The bundled sample replays to the bytes recorded here: tables, manifest, quarantine and the
MCAP files of three episodes of every run. A change of the output bytes must be deliberate:
the digests are then recorded again, with the reason in the commit.

First recorded from commit a5da6f8, before the platform was reshaped into rooms (issue 18).
Recorded again when the steps, episodes and runs tables got their usage, origin,
continuation and completeness columns (issue 19: PROTOCOL §7.2, §7.3, §7.5); every column
that existed before kept its bytes, the goals table, the manifest and the quarantine all of
theirs (checked against the reference engine of the commit before). The MCAP files' again
when the JSON Schema of a step that each of them carries got its description cleaned of the
docstring's indentation, as Python 3.13 compiles it (`record_schema`): the same bytes from
Python 3.11 and 3.13; every message unchanged."""

from __future__ import annotations

import hashlib
from pathlib import Path

import replay
from vge_analytics.synth import image_source

LOGS = Path(__file__).resolve().parents[3] / "logs"
MCAP_EPISODES = ["AirFryer_000-00", "ElectricKettle_000-01", "Microwave_001-02"]

RECORDED = {
    "episodes": "143d89135330b8d3d0cfc57c97e2e081c5ff0f26575108603ce830a89ce3924c",
    "goals": "d5e8445b1e2dbf8b1e8dbbeb8277f8461afae49bb05db6a43cffd8993585548a",
    "manifest.json": "775df39b9bcafbf2b6ef0b33f46b6698cfe90927697a06e0ea80971004d12d5d",
    "mcap": "8e8875a672008212746542c23adee8e24d6b15f6de9baba841da8c6cf8df34cd",
    "quarantine.jsonl": "66abf8d167891f079f7f8413dc3c07078017b68fe92ff4b330a233a860775f9a",
    "runs": "3b5451bb04cea05da930f1e8da87716b0feb5bd21433cdd7e1ff2fb9b83c3f07",
    "steps": "536380957de5d6a95ec19abc8c7099154f49a58c9a1004d741ed945277a1ac39",
}
"""sha256 over each top-level entry of OUT: its files' relative paths and contents, in order."""


def digests(out: Path) -> dict[str, str]:
    found: dict[str, hashlib._Hash] = {}
    for path in sorted(p for p in out.rglob("*") if p.is_file()):
        rel = path.relative_to(out)
        if rel.parts[0] == ".replay":  # private state (the lock)
            continue
        h = found.setdefault(rel.parts[0], hashlib.sha256())
        h.update(str(rel).encode() + b"\0" + hashlib.sha256(path.read_bytes()).digest())
    return {name: h.hexdigest() for name, h in sorted(found.items())}


def test_the_bundled_sample_replays_to_the_recorded_bytes(tmp_path: Path, monkeypatch) -> None:
    # The manifest records the inputs as given: relative to the checkout, wherever it is.
    monkeypatch.chdir(LOGS.parent)
    runs = sorted(Path("logs/runs") / p.name for p in (LOGS / "runs").iterdir() if p.is_dir())
    bench = Path("logs/bench")
    replay.replay_runs(
        runs,
        bench,
        tmp_path / "out",
        mcap_episodes=MCAP_EPISODES,
        image_source=image_source(bench),
        progress=False,
    )
    assert digests(tmp_path / "out") == RECORDED
