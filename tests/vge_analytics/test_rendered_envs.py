"""`vge_analytics.rendered_envs`: `gymnasium.make("vge_analytics.rendered_envs:vge/RenderedDevice-v0",
...)` in a fresh interpreter with nothing imported shows the rendered views of the bundled
benchmark (it has no picture files), with no warning; and each id is registered by one
module, so the same id builds the same environment whatever the order of the imports.

The registry is global to a process: tests that look at it run in a fresh interpreter."""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import replay
from replay.env import DeviceEnv, DeviceRLEnv, no_images
from vge_analytics import synth
from vge_analytics.rendered_envs import device_env, device_rl_env

LOGS_BENCH = Path(__file__).resolve().parents[2] / "logs" / "bench"
SIZE = {"image_width": 32, "image_height": 24}
EPISODE = "AirFryer_000-02"
IDS = ("vge/Device-v0", "vge/DeviceRL-v0", "vge/RenderedDevice-v0", "vge/RenderedDeviceRL-v0")


def _python(code: str, cache: Path) -> dict:
    """Run `code` in a fresh interpreter where any warning is an error; its last line of
    output is JSON."""
    env = {**os.environ, "VGE_CACHE_DIR": str(cache)}
    done = subprocess.run(
        [sys.executable, "-W", "error", "-c", code, str(LOGS_BENCH)],
        capture_output=True, text=True, env=env, timeout=120, check=False,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout.splitlines()[-1])


def _digest(image: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(image).tobytes()).hexdigest()


def _first_image(env: DeviceEnv) -> np.ndarray:
    return env.reset(options={"episode_id": EPISODE})[0]["image"]


MAKE_WITH_NO_IMPORT = f"""
import hashlib, json, sys
import gymnasium, numpy as np

env = gymnasium.make("vge_analytics.rendered_envs:vge/RenderedDevice-v0", bench=sys.argv[1], **{SIZE!r})
obs, _ = env.reset(options={{"episode_id": {EPISODE!r}}})
rl = gymnasium.make("vge/RenderedDeviceRL-v0", bench=sys.argv[1], **{SIZE!r})
rl_obs, _ = rl.reset(options={{"episode_id": {EPISODE!r}}})
envs = gymnasium.make_vec(
    "vge_analytics.rendered_envs:vge/RenderedDeviceRL-v0", num_envs=2, vectorization_mode="async",
    bench=sys.argv[1], **{SIZE!r},
)
batch, _ = envs.reset(options={{"episode_id": {EPISODE!r}}})
envs.close()
print(json.dumps({{
    "entry_points": [gymnasium.spec(i).entry_point for i in {IDS!r}],
    "view": obs["view"],
    "image": hashlib.sha256(obs["image"].tobytes()).hexdigest(),
    "same_in_rl": bool(np.array_equal(rl_obs["image"], obs["image"])),
    "same_in_workers": bool(np.array_equal(batch["image"][1], obs["image"])),
}}))
"""


def test_make_with_no_import_shows_the_rendered_views(tmp_path: Path) -> None:
    got = _python(MAKE_WITH_NO_IMPORT, tmp_path / "cache")
    assert got["entry_points"] == [
        "replay.env._env:DeviceEnv",
        "replay.env._rl:DeviceRLEnv",
        "vge_analytics.rendered_envs:device_env",
        "vge_analytics.rendered_envs:device_rl_env",
    ]
    bench = replay.Benchmark.open(LOGS_BENCH)
    machine = bench.machine("AirFryer_000")
    assert got["view"] == "front" and synth.view_image(LOGS_BENCH, machine, "front") is not None
    rendered = DeviceEnv(bench, image_source=synth.image_source(LOGS_BENCH), **SIZE)
    assert got["image"] == _digest(_first_image(rendered))
    assert got["image"] != _digest(_first_image(DeviceEnv(bench, image_source=no_images, **SIZE)))
    assert got["same_in_rl"] and got["same_in_workers"]


def _imports(modules: tuple[str, ...], ids: tuple[str, ...] = IDS) -> str:
    """Import modules in this order, then make each id: its entry point and the digest of
    its first image."""
    lines = "".join(f"import {m}; " for m in modules)
    return f"""
import hashlib, json, sys
import gymnasium
{lines}
got = {{}}
for env_id in {ids!r}:
    obs, _ = gymnasium.make(env_id, bench=sys.argv[1], **{SIZE!r}).reset(
        options={{"episode_id": {EPISODE!r}}}
    )
    got[env_id] = [
        gymnasium.spec(env_id).entry_point, hashlib.sha256(obs["image"].tobytes()).hexdigest()
    ]
print(json.dumps(got))
"""


def test_each_id_builds_the_same_env_whatever_is_imported_in_whatever_order(
    tmp_path: Path,
) -> None:
    """The engine's ids alone, then with the analytics' module imported after, then before:
    each id gives the same entry point and the same first image every time (when the
    analytics replaced the engine's registrations, `vge/Device-v0` showed rendered views only
    once `vge_analytics` was imported)."""
    engine_only = _python(_imports(("replay.env",), IDS[:2]), tmp_path)
    engine_first = _python(_imports(("replay.env", "vge_analytics.rendered_envs")), tmp_path)
    analytics_first = _python(_imports(("vge_analytics.rendered_envs", "replay.env")), tmp_path)
    assert engine_first == analytics_first
    assert engine_only == {i: engine_first[i] for i in IDS[:2]}
    bench = replay.Benchmark.open(LOGS_BENCH)
    own = _digest(_first_image(DeviceEnv(bench, **SIZE)))  # the benchmark's pictures only
    source = synth.image_source(LOGS_BENCH)
    rendered = _digest(_first_image(DeviceEnv(bench, image_source=source, **SIZE)))
    assert own != rendered  # the bundled benchmark has no pictures: a canvas naming the view
    assert {i: image for i, (_, image) in engine_first.items()} == {
        "vge/Device-v0": own,
        "vge/DeviceRL-v0": own,
        "vge/RenderedDevice-v0": rendered,
        "vge/RenderedDeviceRL-v0": rendered,
    }


def test_the_functions_take_an_image_source_and_the_options(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("VGE_CACHE_DIR", str(tmp_path / "cache"))
    canvas = _first_image(DeviceEnv(LOGS_BENCH, image_source=no_images, **SIZE))
    rendered = _first_image(
        DeviceEnv(LOGS_BENCH, image_source=synth.image_source(LOGS_BENCH), **SIZE)
    )
    shown = device_env(LOGS_BENCH, image_source=no_images, lam=2, **SIZE)
    assert type(shown) is DeviceEnv and shown.lam == 2.0
    assert np.array_equal(_first_image(shown), canvas)
    rl = device_rl_env(replay.Benchmark.open(LOGS_BENCH), grid=10, **SIZE)
    assert type(rl) is DeviceRLEnv and rl.action_space.nvec.tolist() == [7, 10, 10, 9]
    assert np.array_equal(_first_image(rl), rendered)
