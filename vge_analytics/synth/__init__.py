"""The synthetic VGEBench: device categories, SSM instantiation, rendered views, tasks and
simulated agents (docs/SYNTHETIC.md).

`generate` is what `vge synth` runs; the other names are its parts, for tests and tools.
"""

from typing import TYPE_CHECKING

from replay import lazy_names

if TYPE_CHECKING:  # the names, imported when first used (`lazy_names`)
    from ._agent import Agent, AgentStep
    from ._build import (
        BENCH_DIR,
        RUNS_DIR,
        SCALES,
        SUMMARY,
        Scale,
        Summary,
        SynthError,
        generate,
        plan_devices,
    )
    from ._catalog import (
        PAPER_DEVICE_COUNTS,
        Catalog,
        ComponentSpec,
        available_categories,
        is_known_category,
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
    from ._runs import RunSpec, agent_rng, run_specs
    from ._step_player import StepPlayer, play_episode
    from ._tasks import TaskRecord, sample_tasks
    from ._views import cache_dir, image_source, synthetic_view, view_image

__all__ = [
    "BENCH_DIR",
    "RUNS_DIR",
    "SUMMARY",
    "PAPER_DEVICE_COUNTS",
    "PROFILES",
    "SCALES",
    "Agent",
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
    "agent_rng",
    "available_categories",
    "cache_dir",
    "device_logic",
    "dump_ssm",
    "generate",
    "image_source",
    "instantiate_device",
    "is_known_category",
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
    "synthetic_view",
    "view_image",
]

__getattr__, __dir__ = lazy_names(__name__, __file__)
