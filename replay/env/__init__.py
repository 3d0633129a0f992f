"""The live environment: `vge/Device-v0`, a Gymnasium wrapper over the episode the replay plays."""

import gymnasium

from ._env import STEP_FIELDS, DeviceEnv, log_step_of
from ._images import no_images

ENV_ID = "vge/Device-v0"
"""`gymnasium.make(ENV_ID, bench=PATH)` once this package is imported."""

# Importing the package registers the environment, as Gymnasium's own packages do.
if ENV_ID not in gymnasium.registry:
    gymnasium.register(id=ENV_ID, entry_point="replay.env._env:DeviceEnv")

__all__ = [
    "ENV_ID",
    "STEP_FIELDS",
    "DeviceEnv",
    "log_step_of",
    "no_images",
]
