"""`sim:PROFILE` agents: the profiles of `vge synth` played through the environment make the
same choices as in the bundled synthetic runs, and their runs replay with zero divergence."""

from __future__ import annotations

import gzip
import json
from pathlib import Path

import replay
from vge_analytics.cli import main

LOGS = Path(__file__).resolve().parents[3] / "logs"


def _synth_steps(run: str) -> dict[str, list]:
    path = LOGS / "runs" / run / "episodes.jsonl.gz"
    out = {}
    for line in gzip.decompress(path.read_bytes()).splitlines():
        episode = json.loads(line)
        out[episode["episode_id"]] = episode["steps"]
    return out


def _without_time(steps: list[dict]) -> list[dict]:
    return [{k: v for k, v in s.items() if k != "timestamp"} for s in steps]


def test_the_profiles_play_as_in_the_synthetic_runs(tmp_path: Path) -> None:
    bench = LOGS / "bench"
    chosen = list(replay.Benchmark.open(bench).tasks)[::20]
    for agent, run_id, history in (
        ("sim:f", "sim-vlm-f-hist3", "3"),
        ("sim:human", "sim-human", None),
    ):
        expected = _synth_steps(run_id)
        episodes = [e for e in chosen if e in expected][:8]
        out = tmp_path / run_id
        args = ["run", str(bench), "--agent", agent, "--out", str(out), "--run-id", run_id]
        args += ["--episodes", ",".join(episodes), "--no-progress"]
        if history is not None:
            args += ["--history", history]
        assert main(args) == 0
        lines = [json.loads(line) for line in (out / "episodes.jsonl").read_text().splitlines()]
        assert [e["episode_id"] for e in lines] == episodes
        for episode in lines:
            # Same responses, same recorded view, feedback and state; only `vge synth`
            # invents timestamps (and writes human clicks as integers).
            got = _without_time(episode["steps"])
            want = _without_time(expected[episode["episode_id"]])
            for s in want:
                if "action" in s and s["action"]["coord"] is not None:
                    s["action"]["coord"] = [float(v) for v in s["action"]["coord"]]
            assert got == want, episode["episode_id"]
        header = replay.read_run_header(out)
        assert header.meta["simulated"] is True and header.meta["seed"] == 0
        manifest = replay.replay_runs([out], bench, tmp_path / f"out-{run_id}", progress=False)
        counts = manifest.run(run_id).counts
        assert (counts.replayed, counts.diverged_steps) == (len(episodes), 0)
