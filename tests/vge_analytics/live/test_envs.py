"""`vge_analytics.envs`: `gymnasium.make("vge_analytics.envs:vge/Device-v0", ...)` in a fresh
interpreter with nothing imported shows the rendered views of the bundled benchmark (it has
no picture files), with no warning; it replaces `replay.env`'s registrations whatever the
order of the imports, and leaves a registration of someone else alone.

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
from vge_analytics.envs import device_env, device_rl_env

LOGS_BENCH = Path(__file__).resolve().parents[3] / "logs" / "bench"
SIZE = {"image_width": 32, "image_height": 24}
EPISODE = "AirFryer_000-02"


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

env = gymnasium.make("vge_analytics.envs:vge/Device-v0", bench=sys.argv[1], **{SIZE!r})
obs, _ = env.reset(options={{"episode_id": {EPISODE!r}}})
rl = gymnasium.make("vge/DeviceRL-v0", bench=sys.argv[1], **{SIZE!r})
rl_obs, _ = rl.reset(options={{"episode_id": {EPISODE!r}}})
envs = gymnasium.make_vec(
    "vge_analytics.envs:vge/DeviceRL-v0", num_envs=2, vectorization_mode="async",
    bench=sys.argv[1], **{SIZE!r},
)
batch, _ = envs.reset(options={{"episode_id": {EPISODE!r}}})
envs.close()
print(json.dumps({{
    "entry_points": [gymnasium.spec(i).entry_point for i in ("vge/Device-v0", "vge/DeviceRL-v0")],
    "view": obs["view"],
    "image": hashlib.sha256(obs["image"].tobytes()).hexdigest(),
    "same_in_rl": bool(np.array_equal(rl_obs["image"], obs["image"])),
    "same_in_workers": bool(np.array_equal(batch["image"][1], obs["image"])),
}}))
"""


def test_make_with_no_import_shows_the_rendered_views(tmp_path: Path) -> None:
    got = _python(MAKE_WITH_NO_IMPORT, tmp_path / "cache")
    assert got["entry_points"] == [
        "vge_analytics.envs:device_env",
        "vge_analytics.envs:device_rl_env",
    ]
    bench = replay.Benchmark.open(LOGS_BENCH)
    machine = bench.machine("AirFryer_000")
    assert got["view"] == "front" and synth.view_image(LOGS_BENCH, machine, "front") is not None
    rendered = DeviceEnv(bench, image_source=synth.image_source(LOGS_BENCH), **SIZE)
    assert got["image"] == _digest(_first_image(rendered))
    assert got["image"] != _digest(_first_image(DeviceEnv(bench, image_source=no_images, **SIZE)))
    assert got["same_in_rl"] and got["same_in_workers"]


REGISTRATION_ORDER = """
import json, warnings
import gymnasium
import replay.env

before = gymnasium.spec("vge/Device-v0").entry_point
import vge_analytics.envs

after = [gymnasium.spec(i).entry_point for i in ("vge/Device-v0", "vge/DeviceRL-v0")]
vge_analytics.envs.register_envs()  # again: nothing changes, nothing warns
gymnasium.registry.pop("vge/DeviceRL-v0")
gymnasium.register(id="vge/DeviceRL-v0", entry_point="replay.env._rl:DeviceRLEnv", kwargs={"grid": 5})
vge_analytics.envs.register_envs()  # a registration with other settings is someone else's
print(json.dumps({
    "before": before,
    "after": after,
    "again": [gymnasium.spec(i).entry_point for i in ("vge/Device-v0", "vge/DeviceRL-v0")],
    "kept": gymnasium.spec("vge/DeviceRL-v0").kwargs,
}))
"""


def test_the_analytics_registration_replaces_replays_without_a_warning(tmp_path: Path) -> None:
    got = _python(REGISTRATION_ORDER, tmp_path / "cache")
    assert got["before"] == "replay.env._env:DeviceEnv"
    assert got["after"] == ["vge_analytics.envs:device_env", "vge_analytics.envs:device_rl_env"]
    assert got["again"] == ["vge_analytics.envs:device_env", "replay.env._rl:DeviceRLEnv"]
    assert got["kept"] == {"grid": 5}


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
