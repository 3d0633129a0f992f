"""`vge/RenderedDevice-v0` and `vge/RenderedDeviceRL-v0`: the replay's environments showing
the rendered views of the synthetic categories where a benchmark has no picture.

`replay.env` registers `vge/Device-v0` and `vge/DeviceRL-v0`, which show the benchmark's own
pictures (`replay.BenchImages`). Importing this module registers two more ids, built by the
two functions below: with no `image_source`, an environment shows the benchmark's pictures
and, for devices of the synthetic categories, their rendered views
(`vge_analytics.synth.image_source`), so the bundled benchmark, which has no picture files,
shows its devices. Each id has one registration, made by one module, so what
`gymnasium.make` builds does not depend on the order of the imports.

Gymnasium 1.x no longer loads entry-point plugins (the `gymnasium.envs` group was read by
Gymnasium 0.x only), so nothing registers the ids at `import gymnasium`. Its
`module:id` form imports the module first, in the process that calls `make` and in the
workers of an async vector env alike:

    gymnasium.make("vge_analytics.rendered_envs:vge/RenderedDeviceRL-v0", bench="logs/bench")
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import gymnasium

import replay
from replay.env import DeviceEnv, DeviceRLEnv

from .synth import image_source as rendered_images

RENDERED_ENV_ID = "vge/RenderedDevice-v0"
"""`vge/Device-v0` with the rendered views: `gymnasium.make(RENDERED_ENV_ID, bench=PATH)`."""
RENDERED_RL_ENV_ID = "vge/RenderedDeviceRL-v0"
"""`vge/DeviceRL-v0` with the rendered views."""

ENTRY_POINTS = {
    RENDERED_ENV_ID: f"{__name__}:device_env",
    RENDERED_RL_ENV_ID: f"{__name__}:device_rl_env",
}
"""The ids this module registers, and what builds them."""


def _images(
    bench: str | Path | replay.Benchmark, given: replay.ImageSource | None
) -> replay.ImageSource:
    if given is not None:
        return given
    return rendered_images(bench.root if isinstance(bench, replay.Benchmark) else bench)


def device_env(
    bench: str | Path | replay.Benchmark,
    *,
    image_source: replay.ImageSource | None = None,
    **options: Any,
) -> DeviceEnv:
    """`vge/RenderedDevice-v0`: `replay.env.DeviceEnv` (and its options) with the rendered
    synthetic views."""
    return DeviceEnv(bench, image_source=_images(bench, image_source), **options)


def device_rl_env(
    bench: str | Path | replay.Benchmark,
    *,
    image_source: replay.ImageSource | None = None,
    **options: Any,
) -> DeviceRLEnv:
    """`vge/RenderedDeviceRL-v0`: `replay.env.DeviceRLEnv` (and its options) with the
    rendered synthetic views."""
    return DeviceRLEnv(bench, image_source=_images(bench, image_source), **options)


for _env_id, _entry_point in ENTRY_POINTS.items():
    if _env_id not in gymnasium.registry:
        gymnasium.register(id=_env_id, entry_point=_entry_point)

__all__ = [
    "ENTRY_POINTS",
    "RENDERED_ENV_ID",
    "RENDERED_RL_ENV_ID",
    "device_env",
    "device_rl_env",
]
