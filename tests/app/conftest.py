"""Fixtures of the dashboard tests: a replayed tiny synthetic benchmark, built once.

`vge synth --scale tiny` (8 devices, 24 episodes, nine runs: six simulated VLM profiles, a
human-like run and two history-length variants of one profile) replayed with
`replay.replay_runs`, MCAP files written for the first episode only (`mcap_episode`), so
the viewer's download of an episode without a file (made on demand) is exercised too.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import replay
import vge_analytics as va
from vge_analytics.commands.replay import image_source
from vge_analytics.synth import generate

APP = Path(__file__).resolve().parents[2] / "app" / "streamlit_app.py"


def first_episode(bench: Path) -> str:
    """The smallest episode id of a benchmark's tasks."""
    ids = [json.loads(line)["episode_id"] for line in bench.joinpath("tasks.jsonl").open()]
    return min(ids)


def build_tiny(root: Path) -> Path:
    """Synthesize the tiny benchmark under `root` and replay it into `root/out` (MCAP for
    the first episode only)."""
    bench = root / "synth" / "bench"
    generate(root / "synth", scale="tiny", seed=0, workers=1)
    runs = sorted(p for p in (root / "synth" / "runs").iterdir() if p.is_dir())
    out = root / "out"
    replay.replay_runs(
        runs,
        bench,
        out,
        mcap_episodes=[first_episode(bench)],
        image_source=image_source(bench),  # as `vge replay --mcap` does
        progress=False,
    )
    return out


@pytest.fixture(scope="session", autouse=True)
def cache_dir(tmp_path_factory) -> Path:
    """Rendered views and stored sweeps go to a temporary cache, not the user's."""
    path = tmp_path_factory.mktemp("vge-cache")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("VGE_CACHE_DIR", str(path))
        yield path


@pytest.fixture(scope="session")
def tiny_out(tmp_path_factory, cache_dir) -> Path:
    out = build_tiny(tmp_path_factory.mktemp("app"))
    yield out
    va.clear_cache()


@pytest.fixture(scope="session")
def mcap_episode(tiny_out) -> str:
    """The episode whose MCAP files the replay wrote."""
    return first_episode(tiny_out.parent / "synth" / "bench")


@pytest.fixture
def app_env(tiny_out, monkeypatch) -> Path:
    """The app reads OUT from $VGE_APP_OUT (as `vge app` sets it)."""
    monkeypatch.setenv("VGE_APP_OUT", str(tiny_out))
    return tiny_out
