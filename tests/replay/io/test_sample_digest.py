"""The bundled sample replays to the same bytes it did before the platform was reshaped into
rooms (issue 18: rules stated once, vge_analytics in subpackages): the digests below were
recorded from the replay output of commit a5da6f8, tables, manifest, quarantine and the MCAP
files of three episodes of every run. A change of the output bytes must be deliberate: the
digests are then recorded again, with the reason in the commit."""

from __future__ import annotations

import hashlib
from pathlib import Path

import replay
from vge_analytics.synth import image_source

LOGS = Path(__file__).resolve().parents[3] / "logs"
MCAP_EPISODES = ["AirFryer_000-00", "ElectricKettle_000-01", "Microwave_001-02"]

RECORDED = {
    "episodes": "38f1e369fbaf3ffee344dd39b45480a814741e7e8df3fc8699bc06b42839874d",
    "goals": "d5e8445b1e2dbf8b1e8dbbeb8277f8461afae49bb05db6a43cffd8993585548a",
    "manifest.json": "775df39b9bcafbf2b6ef0b33f46b6698cfe90927697a06e0ea80971004d12d5d",
    "mcap": "c6e0917a81f3727995a15727da16d3dba7fbf7550b904463db36a7851e28eb6e",
    "quarantine.jsonl": "66abf8d167891f079f7f8413dc3c07078017b68fe92ff4b330a233a860775f9a",
    "runs": "a75dda8cf5441482cd7b7059115f12cc83b0f8a505f1f48914bf82305a366a52",
    "steps": "878626c20dc2cb55c644d43f622952e0fad4dcf6cef84fb05d8f6f5176162447",
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
