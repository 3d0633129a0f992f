"""Fixtures of the dashboard tests: a replayed tiny synthetic benchmark, built once, and the
dashboard served from it to a browser.

`vge synth --scale tiny` (8 devices, 24 episodes, nine runs: six simulated VLM profiles, a
human-like run and two history-length variants of one profile) replayed with
`replay.replay_runs`, MCAP files written for the first episode only (`mcap_episode`), so
the viewer's download of an episode without a file (made on demand) is exercised too.

Browser fixtures (Playwright through pytest-playwright, Debian's Chromium):
- `app_server`: one `vge app` per test session on the tiny output (`AppServer`), with small
  SQL limits (`SQL_LIMITS`) so the runaway-query tests take seconds, under an address-space
  bound (`SERVER_ADDRESS_SPACE`);
- `app_page`: a fresh browser page on it (`AppPage`: open, navigate, run a query, wait until
  rendered, read tables).
- `play_server`: `vge play` on the tiny benchmark, writing a fresh human run (`PlayServer`).
Tests that use `app_server` or `play_server` run in one xdist group (`browser`), so the
session starts one Chromium.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import NamedTuple

import pytest

import replay
import vge_analytics as va
from vge_analytics.synth import generate, image_source

from ..vge_analytics.metrics.metric_files import SR_AS_SSR, SR_MULTI, write_folder
from .streamlit_browser import CHROMIUM, LAUNCH_ARGS, AppPage, AppServer, served

APP = Path(__file__).resolve().parents[2] / "app" / "streamlit_app.py"
ARTIFACTS = Path(__file__).resolve().parents[1] / "_artifacts"
"""Screenshots of the browser tests (gitignored)."""

SQL_LIMITS = {"timeout": 2.0, "memory": 256 * 1024**2, "rows": 1000}
"""The test server's SQL page limits: small, so a runaway query ends within seconds."""
SERVER_ADDRESS_SPACE = 8 * 1024**3
"""Address space the test server and the processes it starts may map: a safety net against
a regression taking the machine down, not the bound under test (the tests assert resident
memory). It is well above what the server maps: each thread its web server starts for a
request reserves a stack and, with glibc, a malloc arena of up to 64 MB, so the server's
address space grows with request concurrency (1.5 GB in a local run; a CI run reached a 3 GB bound) while
its resident memory stays flat."""


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


def build_seeded(root: Path) -> Path:
    """The tiny benchmark with three seeds of two simulated runs (`vge synth --seeds 3
    --runs sim-vlm-f,sim-human`) and two of sim-vlm-d, replayed into `root/out`."""
    generate(root / "synth", scale="tiny", seed=0, workers=1, agent_seeds=3,
             only_runs=["sim-vlm-f", "sim-human"])  # fmt: skip
    generate(root / "more", scale="tiny", seed=0, workers=1, agent_seeds=2, only_runs=["sim-vlm-d"])
    runs = sorted(
        p for base in ("synth", "more") for p in (root / base / "runs").iterdir() if p.is_dir()
    )
    out = root / "out"
    replay.replay_runs(runs, root / "synth" / "bench", out, progress=False)
    return out


@pytest.fixture(scope="session")
def seeded_out(tmp_path_factory, cache_dir) -> Path:
    """`build_seeded`: repeated runs for the Significance page (built once per session)."""
    return build_seeded(tmp_path_factory.mktemp("seeded"))


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


@pytest.fixture(scope="session")
def metrics_folder(tmp_path_factory) -> Path:
    """A metrics folder: SR overridden (partial credit per goal, SSR's definition) and
    SR-multi (SR over the episodes with more than one goal) added."""
    root = tmp_path_factory.mktemp("metrics") / "mine"
    return write_folder(root, {"sr.sql": SR_AS_SSR, "multi.sql": SR_MULTI})


@pytest.fixture
def metrics_env(metrics_folder, monkeypatch) -> Path:
    """The app runs with `metrics_folder` (through $VGE_METRICS_DIR, as `vge app` passes
    --metrics-dir)."""
    monkeypatch.setenv("VGE_METRICS_DIR", str(metrics_folder))
    return metrics_folder


# ---------------------------------------------------------------------------- browser


SERVERS = {"app_server", "play_server"}


def pytest_collection_modifyitems(items) -> None:
    for item in items:
        if SERVERS & set(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.xdist_group("browser"))


@pytest.fixture(scope="session")
def browser_type_launch_args(browser_type_launch_args) -> dict:
    assert Path(CHROMIUM).exists(), "Debian's chromium is needed (scripts/test.sh installs it)"
    return {**browser_type_launch_args, **LAUNCH_ARGS}


@pytest.fixture(scope="session")
def browser_context_args(browser_context_args) -> dict:
    return {**browser_context_args, "viewport": {"width": 1400, "height": 1600}}


@pytest.fixture(scope="session")
def app_server(tiny_out, tmp_path_factory):
    """`vge app` on the tiny output (its default address), with the small `SQL_LIMITS`."""
    options = [
        "--sql-timeout",
        str(SQL_LIMITS["timeout"]),
        "--sql-memory-limit",
        str(SQL_LIMITS["memory"]),
        "--sql-max-rows",
        str(SQL_LIMITS["rows"]),
    ]
    log = tmp_path_factory.mktemp("server") / "vge-app.log"
    with AppServer(tiny_out, options=options, log=log, address_space=SERVER_ADDRESS_SPACE) as s:
        yield s
    assert "Traceback" not in s.text(), s.text()


@pytest.fixture
def app_page(page, app_server) -> AppPage:
    """A new browser page (its own context) on the test server."""
    return AppPage(page, app_server.url)


class PlayServer(NamedTuple):
    server: AppServer
    bench: Path
    run: Path


@pytest.fixture
def play_server(tiny_out, tmp_path):
    """`vge play BENCH --out RUN` on the tiny benchmark, RUN a new directory."""
    bench = tiny_out.parent / "synth" / "bench"
    run = tmp_path / "alice"
    log = tmp_path / "vge-play.log"
    options = ["--out", str(run), "--image-width", "480"]
    with served(bench, command="play", options=options, log=log) as server:
        yield PlayServer(server, bench, run)
