"""`vge synth --images`: render every view of every device into `bench/images/`."""

from __future__ import annotations

from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import replay
from replay.io import IMAGES_DIR, SSM_DIR, SSM_SUFFIX, write_atomic

from ._foreign import render_foreign
from ._instantiate import scene_of
from ._render import png_bytes, render_view


def render_device(ssm_path: Path, out_dir: Path) -> int:
    """Write `<out_dir>/<device_id>/<view>.png` for every view of one SSM; returns the count."""
    machine = replay.load_machine(ssm_path)
    geometry = scene_of(machine.ssm, machine.device_id)
    target = out_dir / machine.device_id
    target.mkdir(parents=True, exist_ok=True)
    for view in machine.views:
        if geometry is not None:
            img = render_view(geometry, view)
        else:
            img = render_foreign(machine.ssm, machine.category, view)
        write_atomic(target / f"{view}.png", png_bytes(img), sync=False)
    return len(machine.views)


def _job(args: tuple[Path, Path]) -> int:
    return render_device(*args)


def prerender_images(bench: Path, *, workers: int = 1) -> int:
    """Render all views of all SSMs of a benchmark directory; returns the number of images."""
    paths = sorted((bench / SSM_DIR).glob(f"*{SSM_SUFFIX}"))
    out_dir = bench / IMAGES_DIR
    jobs = [(p, out_dir) for p in paths]
    if workers <= 1:
        return sum(_job(j) for j in jobs)
    with ProcessPoolExecutor(max_workers=workers) as pool:
        return sum(pool.map(_job, jobs, chunksize=2))
