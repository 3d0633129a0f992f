"""Geometry records and projections shared by the layout and the renderer.

The device is modelled in 3D: an axis-aligned body (`x` to the right, `y` from the front to
the back, `z` up) of size `X x Y x Z` (a box, or a vertical cylinder), and each component is an
axis-aligned box on its surface. Every view is a projection of that one model, which is what
keeps a component's position consistent across views.

Orthographic views project to image units `(u, v)` (`v` downwards):

| view   | u       | v       | sees the face at |
|--------|---------|---------|------------------|
| front  | x       | Z - z   | y = 0            |
| back   | X - x   | Z - z   | y = Y            |
| left   | Y - y   | Z - z   | x = 0            |
| right  | y       | Z - z   | x = X            |
| top    | x       | Y - y   | z = Z            |
| bottom | x       | y       | z = 0            |

The two axonometric views are orthographic projections along a tilted direction: `front_top`
looks from the front-right and above, `back_bottom` from the back-left and below.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from replay import AXONOMETRIC_VIEWS, DASHBOARD
from replay.semantics import BACK, BOTTOM, FRONT, LEFT, RIGHT, TOP

from ._catalog import ComponentSpec

# Outward normal of each face.
FACE_NORMALS: dict[str, tuple[int, int, int]] = {
    FRONT: (0, -1, 0),
    BACK: (0, 1, 0),
    LEFT: (-1, 0, 0),
    RIGHT: (1, 0, 0),
    TOP: (0, 0, 1),
    BOTTOM: (0, 0, -1),
}
FACE_AXIS = {FRONT: 1, BACK: 1, LEFT: 0, RIGHT: 0, TOP: 2, BOTTOM: 2}
FACE_IS_MAX = {
    FRONT: False,
    BACK: True,
    LEFT: False,
    RIGHT: True,
    TOP: True,
    BOTTOM: False,
}
OPPOSITE = {
    FRONT: BACK,
    BACK: FRONT,
    LEFT: RIGHT,
    RIGHT: LEFT,
    TOP: BOTTOM,
    BOTTOM: TOP,
}
# (axis of u, axis of v) of each orthographic view.
VIEW_AXES = {
    FRONT: (0, 2),
    BACK: (0, 2),
    LEFT: (1, 2),
    RIGHT: (1, 2),
    TOP: (0, 1),
    BOTTOM: (0, 1),
}

Dims = tuple[float, float, float]
PixelRect = tuple[int, int, int, int]
"""(x0, y0, x1, y1) in image pixels, x1/y1 exclusive."""


@dataclass(frozen=True, slots=True)
class Box3:
    """An axis-aligned 3D box: `lo` and `hi` corners."""

    lo: tuple[float, float, float]
    hi: tuple[float, float, float]

    def corners(self) -> list[tuple[float, float, float]]:
        return [
            (x, y, z)
            for x in (self.lo[0], self.hi[0])
            for y in (self.lo[1], self.hi[1])
            for z in (self.lo[2], self.hi[2])
        ]

    @property
    def center(self) -> tuple[float, float, float]:
        return tuple((a + b) / 2.0 for a, b in zip(self.lo, self.hi, strict=True))  # type: ignore[return-value]


def project_ortho(view: str, dims: Dims, p: tuple[float, float, float]) -> tuple[float, float]:
    """A 3D point to `(u, v)` units of an orthographic view (table above)."""
    X, Y, Z = dims
    x, y, z = p
    if view == FRONT:
        return x, Z - z
    if view == BACK:
        return X - x, Z - z
    if view == LEFT:
        return Y - y, Z - z
    if view == RIGHT:
        return y, Z - z
    if view == TOP:
        return x, Y - y
    if view == BOTTOM:
        return x, y
    raise ValueError(f"not an orthographic view: {view}")


def silhouette_size(view: str, dims: Dims) -> tuple[float, float]:
    """Width and height, in units, of the body seen in an orthographic view."""
    a, b = VIEW_AXES[view]
    return dims[a], dims[b]


def project_box(view: str, dims: Dims, box: Box3) -> tuple[float, float, float, float]:
    """`(u0, v0, u1, v1)` of a box in an orthographic view."""
    us, vs = zip(*(project_ortho(view, dims, c) for c in (box.lo, box.hi)), strict=True)
    return min(us), min(vs), max(us), max(vs)


@dataclass(frozen=True, slots=True)
class Frame:
    """An orthographic view image: `pixel = offset + units * scale`."""

    view: str
    width: int
    height: int
    scale: float
    ox: float
    oy: float

    def to_px(self, u: float, v: float) -> tuple[float, float]:
        return self.ox + u * self.scale, self.oy + v * self.scale

    def rect_px(self, rect: tuple[float, float, float, float]) -> PixelRect:
        x0, y0 = self.to_px(rect[0], rect[1])
        x1, y1 = self.to_px(rect[2], rect[3])
        ix0, iy0 = max(0, round(x0)), max(0, round(y0))
        ix1, iy1 = min(self.width, round(x1)), min(self.height, round(y1))
        return ix0, iy0, max(ix1, ix0 + 1), max(iy1, iy0 + 1)


@dataclass(frozen=True, slots=True)
class AxoFrame:
    """An axonometric view: orthographic projection onto the screen axes `e_u`, `e_v`."""

    view: str
    width: int
    height: int
    scale: float
    ox: float
    oy: float
    e_u: tuple[float, float, float]
    e_v: tuple[float, float, float]
    toward: tuple[float, float, float]
    """Unit vector from the device to the camera (faces with normal . toward > 0 are seen)."""

    def to_px(self, p: tuple[float, float, float]) -> tuple[float, float]:
        u = sum(a * b for a, b in zip(p, self.e_u, strict=True))
        v = sum(a * b for a, b in zip(p, self.e_v, strict=True))
        return self.ox + u * self.scale, self.oy + v * self.scale

    def depth(self, p: tuple[float, float, float]) -> float:
        """Larger is nearer to the camera."""
        return sum(a * b for a, b in zip(p, self.toward, strict=True))

    def sees(self, face: str) -> bool:
        n = FACE_NORMALS[face]
        return sum(a * b for a, b in zip(n, self.toward, strict=True)) > 1e-9


def axo_axes(view: str) -> tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...]]:
    """(e_u, e_v, toward) of an axonometric view."""
    yaw = math.radians(32.0)
    pitch = math.radians(28.0)
    # The first axonometric view looks from the front-right and above, the second from
    # exactly the opposite direction.
    if view not in AXONOMETRIC_VIEWS:
        raise ValueError(f"not an axonometric view: {view}")
    sign = 1.0 if view == AXONOMETRIC_VIEWS[0] else -1.0
    c = (
        sign * (math.sin(yaw) * math.cos(pitch)),
        sign * -(math.cos(yaw) * math.cos(pitch)),
        sign * math.sin(pitch),
    )
    # Screen right = forward x up, forward = -c, up = +z.
    right = (-c[1], c[0], 0.0)
    norm = math.hypot(right[0], right[1])
    e_u = (right[0] / norm, right[1] / norm, 0.0)
    # Screen down = -(z - (z.c) c), normalised.
    up = (-c[2] * c[0], -c[2] * c[1], 1.0 - c[2] * c[2])
    n_up = math.sqrt(sum(a * a for a in up))
    e_v = tuple(-a / n_up for a in up)
    return e_u, e_v, c


@dataclass(frozen=True, slots=True)
class Style:
    """Deterministic visual choices for one component."""

    color: tuple[int, int, int]
    variant: int
    """Shape variant (e.g. round vs square button), 0..3."""


@dataclass(frozen=True, slots=True)
class Part:
    """A placed component."""

    name: str
    spec: ComponentSpec
    views: tuple[str, ...]
    """Views it is annotated in (orthographic faces, or `dashboard`)."""
    box: Box3
    """Its place on the body (dashboard parts: on the control panel)."""
    style: Style
    orientation: str
    """`h` or `v`: the long axis of sliders, handles and levers in their main view."""
    dash_rect: PixelRect | None = None
    """On the dashboard image, for parts that live on the dashboard."""


@dataclass(frozen=True, slots=True)
class Panel:
    """The control panel whose zoomed image is the dashboard view."""

    face: str
    box: Box3
    region_views: tuple[str, ...]
    width: int
    height: int
    plane_rect: tuple[float, float, float, float]
    """(u0, v0, u1, v1) in units of the face's view that the dashboard image shows."""
    display: PixelRect
    """A non-interactive display drawn on the panel (dashboard pixels)."""

    def plane_to_px(self, u: float, v: float) -> tuple[float, float]:
        u0, v0, u1, v1 = self.plane_rect
        return (u - u0) / (u1 - u0) * self.width, (v - v0) / (v1 - v0) * self.height

    def px_to_plane(self, x: float, y: float) -> tuple[float, float]:
        u0, v0, u1, v1 = self.plane_rect
        return u0 + x / self.width * (u1 - u0), v0 + y / self.height * (v1 - v0)


@dataclass(frozen=True, slots=True)
class Palette:
    body: tuple[int, int, int]
    trim: tuple[int, int, int]
    accent: tuple[int, int, int]
    panel: tuple[int, int, int]
    background: tuple[int, int, int]


@dataclass(frozen=True, slots=True)
class Geometry:
    """Everything about how one device looks; the SSM's bboxes are read off it."""

    device_id: str
    category: str
    body: str
    dims: Dims
    palette: Palette
    frames: dict[str, Frame]
    axo_frames: dict[str, AxoFrame]
    parts: tuple[Part, ...]
    panel: Panel | None
    model_name: str

    def view_size(self, view: str) -> tuple[int, int]:
        if view in self.frames:
            f = self.frames[view]
            return f.width, f.height
        if view in self.axo_frames:
            a = self.axo_frames[view]
            return a.width, a.height
        if view == DASHBOARD and self.panel is not None:
            return self.panel.width, self.panel.height
        raise KeyError(view)

    def part_rect(self, part: Part, view: str) -> PixelRect:
        """Pixel rect of a part in a view where it is annotated."""
        if view == DASHBOARD:
            assert part.dash_rect is not None
            return part.dash_rect
        frame = self.frames[view]
        return frame.rect_px(project_box(view, self.dims, part.box))

    def bboxes(self) -> dict[str, dict[str, list[int]]]:
        """component -> view -> `[x, y, w, h, W, H]` (PROTOCOL §1.2)."""
        out: dict[str, dict[str, list[int]]] = {}
        for part in self.parts:
            per: dict[str, list[int]] = {}
            for view in part.views:
                x0, y0, x1, y1 = self.part_rect(part, view)
                w, h = self.view_size(view)
                per[view] = [x0, y0, x1 - x0, y1 - y0, w, h]
            out[part.name] = per
        return out

    def regions(self) -> list[dict]:
        """The dashboard extension's regions (PROTOCOL §1.2)."""
        if self.panel is None:
            return []
        out = []
        for view in self.panel.region_views:
            frame = self.frames[view]
            x0, y0, x1, y1 = frame.rect_px(project_box(view, self.dims, self.panel.box))
            out.append(
                {"view": view, "coordinate": [x0, y0, x1 - x0, y1 - y0, frame.width, frame.height]}
            )
        return out
