"""Pictures of a step: a device view with its component boxes and the click."""


from __future__ import annotations

import io
import textwrap
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING

import replay
from replay.io import ssm_path

from .._errors import OutputDirError, UnknownRunError
from ..store import bench_dir
from ..synth import image_source

if TYPE_CHECKING:
    from PIL import Image


@dataclass(frozen=True)
class Box:
    """A component box on the 0..1000 scale of a view, with its role in the picture."""

    component: str
    x0: float
    y0: float
    x1: float
    y1: float
    role: str
    """`target` (a target component of the current state for the current goal), `hit`
    (hit by the click, not a target), `component` (any other component of the view) or
    `optimal` (where the planner's optimal next action acts, PROTOCOL §4.5)."""


ROLE_COLORS: dict[str, tuple[int, int, int]] = {
    "target": (38, 191, 77),
    "hit": (255, 153, 0),
    "component": (120, 120, 120),
    "optimal": (30, 100, 235),
}
"""Box colours, as in the MCAP annotations: targets green, hits orange, others grey; the
side-by-side view's optimal next action blue."""
CLICK_COLOR = (230, 26, 26)


_MOVED = "(the benchmark moved since the replay?)"


@lru_cache(maxsize=8)
def _benchmark(root: str) -> replay.Benchmark:
    return replay.Benchmark.open(root)


def benchmark(bench: Path | replay.Location) -> replay.Benchmark:
    """The benchmark at `bench`, opened once per process: its machines compile once, in its
    own cache (`replay.Benchmark.machine`), for every page and download."""
    try:
        return _benchmark(str(bench))
    except replay.InputError as exc:
        raise OutputDirError(f"{exc} {_MOVED}") from None


def device_machine(out: str | Path, device_id: str, run_id: str | None = None) -> replay.Machine:
    """The compiled SSM of a device, from the benchmark OUT was replayed against."""
    return bench_machine(bench_dir(out, run_id), device_id)


def bench_machine(bench: Path | replay.Location, device_id: str) -> replay.Machine:
    """The compiled SSM of a device of the benchmark at `bench`."""
    opened = benchmark(bench)
    if device_id not in opened.ssm_paths:
        raise OutputDirError(f"{ssm_path(bench, device_id)}: SSM not found {_MOVED}")
    return opened.machine(device_id)


def view_boxes(
    machine: replay.Machine,
    view: str,
    *,
    state: str | None = None,
    goal: str | None = None,
    hit: Sequence[str] = (),
    targets: Sequence[str] | None = None,
) -> list[Box]:
    """Every component box of `view`, each with its role.

    Targets are the target components of `state` for `goal` (PROTOCOL §4) drawn with their
    transitions' bboxes from that state, or, with `targets`, those components' boxes.
    """
    boxes: list[Box] = []
    target_names: set[str] = set()
    if targets is not None:
        target_names = set(targets)
    elif state is not None and goal is not None and state in machine.state_index:
        s, g = machine.state_index[state], machine.state_index.get(goal)
        if g is not None:
            for component, rect in replay.semantics.target_rects(machine, s, g, view):
                target_names.add(component)
                boxes.append(Box(component, *rect[:4], role="target"))
    hit_names = set(hit)
    for component, rect in machine.component_rects.get(view, ()):
        if targets is None and component in target_names:
            continue  # drawn with its state's target rects above
        role = (
            "target"
            if component in target_names
            else "hit"
            if component in hit_names
            else "component"
        )
        boxes.append(Box(component, *rect[:4], role=role))
    order = {"component": 0, "hit": 1, "target": 2}
    return sorted(boxes, key=lambda b: (order[b.role], b.component, b.x0, b.y0))


@dataclass(frozen=True)
class ViewPicture:
    """A device view image, as PNG/JPEG bytes with its pixel size (or a blank stand-in)."""

    data: bytes
    format: str
    width: int
    height: int
    rendered: bool
    """False when the benchmark has no image for the view (a blank canvas stands in)."""
    problem: str | None = None
    """Why the benchmark's own picture is not shown (too large, not a picture), one line
    naming its file; None when it is shown or there is none."""


NO_PICTURE = "no image of this view in the benchmark"
"""What the stand-in of a view without a picture says."""


def view_picture(
    out: str | Path, device_id: str, view: str, run_id: str | None = None
) -> ViewPicture:
    """The image of a device view (rendered synthetic views included), or a blank canvas
    that says why (`replay.io.bench_image_problem`)."""
    bench = bench_dir(out, run_id)  # the manifest read once for the machine and the picture
    machine = bench_machine(bench, device_id)
    got = image_source(bench)(machine, view)
    if got is not None:
        return ViewPicture(*got, rendered=True)
    problem = replay.io.bench_image_problem(bench, machine, view)
    return _stand_in(None if problem is None else str(problem))


def _stand_in(problem: str | None) -> ViewPicture:
    from PIL import Image

    buf = io.BytesIO()
    Image.new("RGB", (600, 600), (236, 238, 242)).save(buf, format="PNG")
    return ViewPicture(buf.getvalue(), "png", 600, 600, False, problem)


def _decoded(picture: ViewPicture) -> tuple[Image.Image, ViewPicture]:
    """The picture as RGB, or the stand-in's when it is refused (`replay.io.decode_picture`
    checks the pixels before decoding; a truncated file is refused too), with the picture
    drawn."""
    try:
        return replay.io.decode_picture(picture.data), picture
    except replay.PictureError as exc:
        stand_in = _stand_in(str(exc))
        return replay.io.decode_picture(stand_in.data), stand_in


def draw_step(
    picture: ViewPicture,
    boxes: Sequence[Box],
    click: tuple[float, float] | None,
    *,
    max_width: int = 720,
) -> bytes:
    """PNG of the view with the component boxes (by role) and the click drawn as a red x."""
    from PIL import ImageDraw

    img, picture = _decoded(picture)
    if img.width > max_width:
        img = img.resize((max_width, round(img.height * max_width / img.width)))
    sx, sy = img.width / replay.SCALE, img.height / replay.SCALE
    draw = ImageDraw.Draw(img)
    if not picture.rendered:
        text = "\n".join(textwrap.wrap(picture.problem or NO_PICTURE, 90))
        draw.multiline_text((10, 10), text, fill=(90, 90, 90))
    for box in boxes:
        width = {"target": 3, "hit": 3, "component": 1, "optimal": 4}[box.role]
        color = ROLE_COLORS[box.role]
        xy = (box.x0 * sx, box.y0 * sy, box.x1 * sx, box.y1 * sy)
        draw.rectangle(xy, outline=color, width=width)
        if box.role != "component" or not picture.rendered:
            draw.text((xy[0] + 3, xy[1] + 2), box.component, fill=color)
    if click is not None:
        cx, cy = click[0] * sx, click[1] * sy
        r = max(6.0, 0.015 * max(img.width, img.height))
        draw.line((cx - r, cy - r, cx + r, cy + r), fill=CLICK_COLOR, width=4)
        draw.line((cx - r, cy + r, cx + r, cy - r), fill=CLICK_COLOR, width=4)
    buf = io.BytesIO()
    img.save(buf, format="PNG")
    return buf.getvalue()


def step_picture(out: str | Path, run_id: str, episode_id: str, step: int) -> bytes:
    """The episode viewer's picture of one step: the view the agent saw, the click (red x),
    the components it hit (orange) and the target components of the current goal (green)."""
    from ..store import steps

    rows = steps(out, where={"run_id": run_id, "episode_id": episode_id, "step": int(step)})
    if rows.height == 0:
        raise UnknownRunError(f"no step {step} in episode {episode_id!r} of run {run_id!r}")
    row = rows.row(0, named=True)
    view = row["view_before"]
    if view is None:
        raise OutputDirError(f"step {step} has no view (it was logged after the episode ended)")
    machine = device_machine(out, row["device_id"], run_id)
    picture = view_picture(out, row["device_id"], view, run_id)
    boxes = view_boxes(
        machine,
        view,
        state=row["state_before"],
        goal=row["goal_state"],
        hit=list(row["hit_components"] or []),
    )
    click = (row["x"], row["y"]) if row["x"] is not None and row["y"] is not None else None
    return draw_step(picture, boxes, click)
