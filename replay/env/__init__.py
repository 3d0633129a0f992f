"""The live environments, Gymnasium wrappers over the episode the replay plays:
`vge/Device-v0` (text in and out, as a model sees the benchmark) and `vge/DeviceRL-v0`
(numbers in and out, for reinforcement learning).

Importing the package registers both ids, with the benchmark's own pictures as their image
source (`replay.BenchImages`; the `image_source` option replaces it). This package is the
one place that registers them: a package built on this one registers ids of its own
(for instance the same environments with rendered views), so what
`gymnasium.make` builds for an id never depends on the order of the imports.
"""

import gymnasium

from ._actions import ACTION_TYPES, CHOICES, DEFAULT_GRID, PARAMETERS, cell_centre
from ._bounds import BenchBounds, bench_bounds
from ._env import STEP_FIELDS, DeviceEnv, log_step_of, step_info
from ._images import no_images
from ._rl import RL_IMAGE_SIZE, DeviceRLEnv

ENV_ID = "vge/Device-v0"
"""`gymnasium.make(ENV_ID, bench=PATH)` once this package is imported."""
RL_ENV_ID = "vge/DeviceRL-v0"
"""`gymnasium.make(RL_ENV_ID, bench=PATH)` once this package is imported."""

ENTRY_POINTS = {
    ENV_ID: "replay.env._env:DeviceEnv",
    RL_ENV_ID: "replay.env._rl:DeviceRLEnv",
}
"""The ids this package registers, and what builds them."""

for _env_id, _entry_point in ENTRY_POINTS.items():
    if _env_id not in gymnasium.registry:  # imported again after a reload: registered once
        gymnasium.register(id=_env_id, entry_point=_entry_point)

__all__ = [
    "ACTION_TYPES",
    "CHOICES",
    "DEFAULT_GRID",
    "ENTRY_POINTS",
    "ENV_ID",
    "PARAMETERS",
    "RL_ENV_ID",
    "RL_IMAGE_SIZE",
    "STEP_FIELDS",
    "BenchBounds",
    "DeviceEnv",
    "DeviceRLEnv",
    "bench_bounds",
    "cell_centre",
    "log_step_of",
    "no_images",
    "step_info",
]
