"""The synthetic VGEBench: device categories, SSM instantiation, rendered views, tasks and
simulated agents (docs/SYNTHETIC.md).

`generate` is what `vge synth` runs; the other names are its parts, for tests and tools.
"""

from ._agent import AgentStep, StepPlayer, play_episode
from ._build import SCALES, Scale, Summary, SynthError, generate, plan_devices
from ._catalog import (
    PAPER_DEVICE_COUNTS,
    Catalog,
    ComponentSpec,
    available_categories,
    load_catalog,
    load_ucsm,
)
from ._instantiate import (
    SyntheticDevice,
    device_logic,
    dump_ssm,
    instantiate_device,
    scene_of,
)
from ._measure import RunMeasures, measure_output
from ._profiles import PROFILES, Profile
from ._render import png_bytes, render_view
from ._runs import RunSpec, run_specs
from ._tasks import TaskRecord, sample_tasks

__all__ = [
    "PAPER_DEVICE_COUNTS",
    "PROFILES",
    "SCALES",
    "AgentStep",
    "Catalog",
    "ComponentSpec",
    "Profile",
    "RunMeasures",
    "RunSpec",
    "Scale",
    "Summary",
    "SynthError",
    "StepPlayer",
    "SyntheticDevice",
    "TaskRecord",
    "available_categories",
    "device_logic",
    "dump_ssm",
    "generate",
    "instantiate_device",
    "load_catalog",
    "load_ucsm",
    "measure_output",
    "play_episode",
    "plan_devices",
    "png_bytes",
    "render_view",
    "run_specs",
    "sample_tasks",
    "scene_of",
]
