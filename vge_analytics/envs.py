"""`vge/Device-v0` and `vge/DeviceRL-v0` showing the analytics' pictures of the views.

Importing this module registers both ids with Gymnasium, built by the two functions below:
with no `image_source`, an environment shows the benchmark's own pictures and, for devices
of the synthetic categories, their rendered views (`vge_analytics.synth.image_source`), so
the bundled benchmark, which has no picture files, shows its devices. `import replay.env`
alone registers the same ids with the benchmark's pictures only; this module replaces those
registrations (and leaves any other registration of the ids alone).

Gymnasium 1.x no longer loads entry-point plugins (the `gymnasium.envs` group was read by
Gymnasium 0.x only), so nothing registers the ids at `import gymnasium`. Its
`module:id` form imports the module first, in the process that calls `make` and in the
workers of an async vector env alike:

    gymnasium.make("vge_analytics.envs:vge/DeviceRL-v0", bench="logs/bench")
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import gymnasium

import replay
from replay.env import ENTRY_POINTS, ENV_ID, RL_ENV_ID, DeviceEnv, DeviceRLEnv

from .synth import image_source as rendered_images

OWN_ENTRY_POINTS = {
    ENV_ID: f"{__name__}:device_env",
    RL_ENV_ID: f"{__name__}:device_rl_env",
}


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
    """`vge/Device-v0` (the options of `replay.env.DeviceEnv`) with rendered synthetic views."""
    return DeviceEnv(bench, image_source=_images(bench, image_source), **options)


def device_rl_env(
    bench: str | Path | replay.Benchmark,
    *,
    image_source: replay.ImageSource | None = None,
    **options: Any,
) -> DeviceRLEnv:
    """`vge/DeviceRL-v0` (the options of `replay.env.DeviceRLEnv`) with rendered synthetic
    views."""
    return DeviceRLEnv(bench, image_source=_images(bench, image_source), **options)


def register_envs() -> None:
    """Register both ids with this module's functions in place of the plain registrations of
    `replay.env` (any other registration of an id, ours included, stays: calling it again
    changes nothing). The old one is removed first, as re-registering an id makes Gymnasium
    warn."""
    for env_id, entry_point in OWN_ENTRY_POINTS.items():
        spec = gymnasium.registry.get(env_id)
        if spec is not None and (spec.entry_point != ENTRY_POINTS[env_id] or spec.kwargs):
            continue
        gymnasium.registry.pop(env_id, None)
        gymnasium.register(id=env_id, entry_point=entry_point)


register_envs()

__all__ = ["OWN_ENTRY_POINTS", "device_env", "device_rl_env", "register_envs"]
