"""The geometric half of SSM instantiation: body size, view images, where each component sits.

`layout()` is a pure function of a `LayoutInput` (the logical SSM, which views each component
is visible in, whether the device has a dashboard): the generator calls it to annotate the SSM
and the renderer calls it again, on the SSM it reads, to draw the same device. Its random
choices come from a generator seeded by a digest of that input, so the two agree exactly.

Placement is rejection sampling: components are placed largest first at random positions
allowed by their faces (one face: anywhere on it; two adjacent faces: on their shared edge),
and a position is accepted only when the component's box, in every view it is annotated in,
keeps a margin from every box already there (and from the dashboard region).
"""

from __future__ import annotations

import hashlib
import json
import math
import random
from dataclasses import dataclass

from replay import AXONOMETRIC_VIEWS as AXO
from replay import DASHBOARD
from replay import ORTHOGRAPHIC_VIEWS as ORTHO
from replay.semantics import BACK, BOTTOM, FRONT, LEFT, PULL, PUSH, RIGHT, TOP

from ._catalog import Catalog, ComponentSpec, load_catalog
from ._geometry import (
    FACE_AXIS,
    FACE_IS_MAX,
    OPPOSITE,
    AxoFrame,
    Box3,
    Dims,
    Frame,
    Geometry,
    Palette,
    Panel,
    Part,
    PixelRect,
    Style,
    axo_axes,
    project_box,
    silhouette_size,
)
from ._shapes import (
    ACCENT_COLORS,
    BACKGROUNDS,
    BODY_COLORS,
    BODY_DIMS,
    DEFAULT_DIMS_BY_SIZE,
    DEVICE_SCALE,
    KIND_PROPORTION,
    ORIENTED_KINDS,
    SIZE_FRACTION,
    darker,
    lighter,
)

LAYOUT_VERSION = "layout-v1"
"""Part of the layout seed: bump when the layout changes so old SSMs are recognised as such."""

GAP = 8
"""Minimum distance, in pixels, between two boxes in a view."""
MIN_BOX = 18
"""Minimum width and height of a box, in pixels."""
_SIZE_ORDER = {"large": 0, "medium": 1, "small": 2, "tiny": 3}
_HORIZONTAL_FACE_ANGLE = {FRONT: 0.0, RIGHT: 90.0, BACK: 180.0, LEFT: 270.0}


class LayoutError(Exception):
    """A component does not fit; `component` names it (None: the dashboard panel)."""

    def __init__(self, message: str, component: str | None = None) -> None:
        super().__init__(message)
        self.component = component


@dataclass(frozen=True, slots=True)
class LayoutInput:
    """What the layout depends on; recoverable from an SSM written by the generator."""

    device_id: str
    category: str
    machine: dict
    """Logical SSM (see `logical_form`)."""
    views: dict[str, tuple[str, ...]]
    """component -> views it is annotated in (catalog face order, or `("dashboard",)`)."""
    dashboard: bool

    def digest(self) -> str:
        payload = {
            "version": LAYOUT_VERSION,
            "device_id": self.device_id,
            "category": self.category,
            "machine": self.machine,
            "views": {k: list(v) for k, v in sorted(self.views.items())},
            "dashboard": self.dashboard,
        }
        text = json.dumps(payload, sort_keys=True, separators=(",", ":"), ensure_ascii=False)
        return hashlib.sha256(text.encode("utf-8")).hexdigest()


def logical_form(name: str, initial_state: str, states: dict) -> dict:
    """The SSM without geometry, canonical: the same for the generator's dict and a loaded SSM.

    `states` maps state -> {"description", "on": {component: [transition]}, "is_error"?} where a
    transition is a dict or an object with `next_state`, `transition_description`,
    `atomic_action`, `parameter` attributes."""

    def get(t, key):
        return t.get(key) if isinstance(t, dict) else getattr(t, key, None)

    out_states = {}
    for sname, sdef in states.items():
        on_in = get(sdef, "on") or {}
        on = {}
        for comp, trans in on_in.items():
            items = []
            for t in trans:
                item = {
                    "next_state": get(t, "next_state"),
                    "transition_description": get(t, "transition_description") or "",
                }
                action = get(t, "atomic_action")
                if action is not None:
                    item["atomic_action"] = str(action).lower()
                    item["parameter"] = [str(p) for p in (get(t, "parameter") or [])]
                items.append(item)
            on[comp] = items
        entry = {"description": get(sdef, "description") or "", "on": on}
        if get(sdef, "is_error"):
            entry["is_error"] = True
        out_states[sname] = entry
    return {"name": name, "initial_state": initial_state, "states": out_states}


# ----------------------------------------------------------------------------- the layout


def layout(inp: LayoutInput) -> Geometry:
    """Place the device and its components; deterministic in `inp`.

    A crowded device that does not fit is laid out again from the next seed of a fixed
    sequence, so the result still depends on `inp` alone."""
    digest = inp.digest()
    error: LayoutError | None = None
    for attempt in range(8):
        rng = random.Random(
            int(hashlib.sha256(f"{digest}:{attempt}".encode()).hexdigest()[:16], 16)
        )
        try:
            return _layout_once(inp, rng)
        except LayoutError as exc:
            error = exc
    assert error is not None
    raise error


def _layout_once(inp: LayoutInput, rng: random.Random) -> Geometry:
    catalog = load_catalog(inp.category)
    body = body_kind(catalog.body)
    dims = _body_dims(inp.category, catalog, body, rng)
    palette = _palette(rng)
    frames = {v: _ortho_frame(v, dims, rng) for v in ORTHO}
    axo_frames = {v: _axo_frame(v, dims, body, rng) for v in AXO}
    model_name = _model_name(inp.category, rng)

    placer = _Placer(dims, body, frames, catalog, rng)
    components = [c for c in catalog.components if c in inp.views]
    on_panel = [c for c in components if inp.views[c] == (DASHBOARD,)]
    if on_panel and not inp.dashboard:
        raise LayoutError(f"{inp.device_id}: dashboard parts without a dashboard")
    regular = [c for c in components if c not in on_panel]
    regular.sort(key=lambda c: _SIZE_ORDER.get(catalog.components[c].size, 2))

    parts: list[Part] = []
    panel: Panel | None = None
    large = [c for c in regular if catalog.components[c].size == "large"]
    rest = [c for c in regular if catalog.components[c].size != "large"]
    for name in large:
        parts.append(placer.place(name, catalog.components[name], inp.views[name], inp.machine))
    if inp.dashboard:
        panel, panel_parts = _place_panel(placer, catalog, on_panel, inp.machine, rng)
        parts.extend(panel_parts)
    for name in rest:
        parts.append(placer.place(name, catalog.components[name], inp.views[name], inp.machine))
    order = {c: i for i, c in enumerate(catalog.components)}
    parts.sort(key=lambda p: order[p.name])
    return Geometry(
        device_id=inp.device_id,
        category=inp.category,
        body=body,
        dims=dims,
        palette=palette,
        frames=frames,
        axo_frames=axo_frames,
        parts=tuple(parts),
        panel=panel,
        model_name=model_name,
    )


def body_kind(name: str) -> str:
    """`cylinder`, `pistol` (a barrel over a grip; placed like a box) or `box`."""
    name = name.lower()
    if name.startswith("cylind"):
        return "cylinder"
    if name == "pistol":
        return "pistol"
    return "box"


def pistol_solids(dims: Dims) -> tuple[Box3, Box3]:
    """(barrel, grip) of a pistol-shaped body: the barrel along the longer horizontal axis."""
    X, Y, Z = dims
    barrel = Box3((0.0, 0.0, Z * 0.5), (X, Y, Z))
    if X >= Y:
        grip = Box3((X * 0.3, Y * 0.12, 0.0), (X * 0.62, Y * 0.88, Z * 0.56))
    else:
        grip = Box3((X * 0.12, Y * 0.3, 0.0), (X * 0.88, Y * 0.62, Z * 0.56))
    return barrel, grip


def _body_dims(category: str, catalog: Catalog, body: str, rng: random.Random) -> Dims:
    base = BODY_DIMS.get(category) or DEFAULT_DIMS_BY_SIZE.get(
        catalog.size, DEFAULT_DIMS_BY_SIZE["medium"]
    )
    x, y, z = (d * rng.uniform(0.85, 1.15) for d in base)
    if body == "cylinder":
        d = (x + y) / 2.0
        return (d, d, z)
    return (x, y, z)


def _palette(rng: random.Random) -> Palette:
    body = rng.choice(BODY_COLORS)
    accent = rng.choice([a for a in ACCENT_COLORS if a != body])
    dark_body = sum(body) < 3 * 110
    trim = lighter(body, 0.35) if dark_body else darker(body, 0.3)
    if rng.random() < 0.5:
        panel = (30, 34, 40)
    else:
        panel = lighter(body, 0.12) if dark_body else darker(body, 0.08)
    return Palette(body, trim, accent, panel, rng.choice(BACKGROUNDS))


def _model_name(category: str, rng: random.Random) -> str:
    letters = "".join(ch for ch in category if ch.isupper())[:2] or category[:2].upper()
    return f"{letters}-{rng.randint(100, 990)}"


def _ortho_frame(view: str, dims: Dims, rng: random.Random) -> Frame:
    a, b = silhouette_size(view, dims)
    long_px = rng.uniform(760.0, 1120.0)
    scale = long_px / max(a, b)
    mx = rng.uniform(0.07, 0.16) * max(a, b) * scale
    my = rng.uniform(0.07, 0.16) * max(a, b) * scale
    width = max(700, round(a * scale + 2 * mx))
    height = max(700, round(b * scale + 2 * my))
    width = min(width, 1420)
    height = min(height, 1420)
    ox = (width - a * scale) / 2.0 + rng.uniform(-0.03, 0.03) * width
    oy = (height - b * scale) / 2.0 + rng.uniform(-0.03, 0.03) * height
    return Frame(view, width, height, scale, ox, oy)


def body_outline_points(
    body: str, dims: Dims, samples: int = 48
) -> list[tuple[float, float, float]]:
    """Points on the body's outline in 3D (corners of the box, or rims of the cylinder)."""
    X, Y, Z = dims
    if body == "cylinder":
        r = X / 2.0
        pts = []
        for i in range(samples):
            t = 2 * math.pi * i / samples
            for z in (0.0, Z):
                pts.append((r + r * math.cos(t), r + r * math.sin(t), z))
        return pts
    return Box3((0.0, 0.0, 0.0), (X, Y, Z)).corners()


def _axo_frame(view: str, dims: Dims, body: str, rng: random.Random) -> AxoFrame:
    e_u, e_v, toward = axo_axes(view)
    pts = body_outline_points(body, dims)
    us = [sum(a * b for a, b in zip(p, e_u, strict=True)) for p in pts]
    vs = [sum(a * b for a, b in zip(p, e_v, strict=True)) for p in pts]
    a, b = max(us) - min(us), max(vs) - min(vs)
    long_px = rng.uniform(760.0, 1080.0)
    scale = long_px / max(a, b)
    margin = rng.uniform(0.08, 0.15) * max(a, b) * scale
    width = min(1420, max(700, round(a * scale + 2 * margin)))
    height = min(1420, max(700, round(b * scale + 2 * margin)))
    ox = (width - a * scale) / 2.0 - min(us) * scale
    oy = (height - b * scale) / 2.0 - min(vs) * scale
    return AxoFrame(view, width, height, scale, ox, oy, e_u, e_v, toward)  # type: ignore[arg-type]


# --------------------------------------------------------------------------- placement


def _orientation(name: str, spec: ComponentSpec, machine: dict, rng: random.Random) -> str:
    """Sliders follow their push/pull directions (0/1 up-down, 2/3 left-right)."""
    dirs = set()
    for sdef in machine["states"].values():
        for t in sdef["on"].get(name, ()):
            if t.get("atomic_action") in (PUSH, PULL) and t.get("parameter"):
                dirs.add(t["parameter"][0])
    draw = rng.random()
    if dirs & {"0", "1"} and not dirs & {"2", "3"}:
        return "v"
    if dirs & {"2", "3"} and not dirs & {"0", "1"}:
        return "h"
    if spec.kind == "slider":
        return "h" if draw < 0.5 else "v"
    return "h" if draw < 0.6 else "v"


class _Placer:
    def __init__(
        self,
        dims: Dims,
        body: str,
        frames: dict[str, Frame],
        catalog: Catalog,
        rng: random.Random,
    ) -> None:
        self.dims = dims
        self.body = body
        self.frames = frames
        self.catalog = catalog
        self.rng = rng
        self.occupied: dict[str, list[PixelRect]] = {v: [] for v in ORTHO}

    # -- sizes -----------------------------------------------------------------------

    def nominal_size(self, spec: ComponentSpec, face: str, orientation: str) -> tuple[float, float]:
        """(w, h) on the main face, in units of that face's view."""
        fw, fh = silhouette_size(face, self.dims)
        rng = self.rng
        if spec.size == "large":
            w = fw * rng.uniform(0.42, 0.62)
            h = fh * rng.uniform(0.5, 0.72)
            aspect = KIND_PROPORTION.get(spec.kind, 1.0)
            if spec.kind in ORIENTED_KINDS:
                if orientation == "v":
                    w = min(w, h / aspect)
                else:
                    h = min(h, w / aspect)
            return w, h
        scale = DEVICE_SCALE.get(self.catalog.size, 0.7)
        s = SIZE_FRACTION.get(spec.size, 0.19) * scale * min(fw, fh) * rng.uniform(0.85, 1.15)
        aspect = KIND_PROPORTION.get(spec.kind, 1.0)
        if spec.kind in ORIENTED_KINDS and orientation == "v":
            aspect = 1.0 / aspect
        w = s * math.sqrt(aspect)
        h = s / math.sqrt(aspect)
        # Never wider or taller than most of the face.
        w = min(w, fw * 0.8)
        h = min(h, fh * 0.8)
        return w, h

    # -- sampling --------------------------------------------------------------------

    def sample_box(self, faces: tuple[str, ...], w: float, h: float) -> Box3:
        """A random box of in-face size (w, h) that sits on `faces`."""
        primary = faces[0]
        u_axis, v_axis = _face_plane_axes(primary)
        size = [0.0, 0.0, 0.0]
        size[u_axis] = w
        size[v_axis] = h
        normal = FACE_AXIS[primary]
        size[normal] = max(w, h) * 0.9 if len(faces) > 1 else min(w, h) * 0.25
        if self.body == "cylinder":
            return self._sample_cylinder(faces, size)
        return self._sample_box_body(faces, size)

    def _axis_range(self, axis: int, faces: tuple[str, ...], s: float) -> tuple[float, float]:
        d = self.dims[axis]
        on_min = any(FACE_AXIS[f] == axis and not FACE_IS_MAX[f] for f in faces)
        on_max = any(FACE_AXIS[f] == axis and FACE_IS_MAX[f] for f in faces)
        p = min(s * 0.12, d * 0.03)
        if on_min and on_max:
            return -p, d + p
        if on_min:
            return -p, min(s, d) - p
        if on_max:
            return d - min(s, d) + p, d + p
        margin = min(d * 0.06, max(0.0, (d - s) / 2.0))
        lo = margin + s / 2.0
        hi = d - margin - s / 2.0
        c = d / 2.0 if hi <= lo else self.rng.uniform(lo, hi)
        return c - s / 2.0, c + s / 2.0

    def _sample_box_body(self, faces: tuple[str, ...], size: list[float]) -> Box3:
        lo, hi = [], []
        for axis in range(3):
            a, b = self._axis_range(axis, faces, size[axis])
            lo.append(a)
            hi.append(b)
        return Box3(tuple(lo), tuple(hi))  # type: ignore[arg-type]

    def _sample_cylinder(self, faces: tuple[str, ...], size: list[float]) -> Box3:
        X, Y, Z = self.dims
        r = X / 2.0
        horizontal = [f for f in faces if f in _HORIZONTAL_FACE_ANGLE]
        z0, z1 = self._axis_range(2, faces, size[2])
        band = any(OPPOSITE[f] in horizontal for f in horizontal)
        if band:
            p = r * 0.04
            return Box3((-p, -p, z0), (X + p, Y + p, z1))
        if horizontal:
            angles = [_HORIZONTAL_FACE_ANGLE[f] for f in horizontal]
            if len(angles) == 1:
                theta = angles[0] + self.rng.uniform(-10.0, 10.0)
            else:
                sx = sum(math.sin(math.radians(a)) for a in angles)
                cx = sum(math.cos(math.radians(a)) for a in angles)
                theta = math.degrees(math.atan2(sx, cx))
            t = math.radians(theta)
            on_top = any(f in (TOP, BOTTOM) for f in faces)
            inset = 0.88 if on_top else 1.0
            px = r + r * inset * math.sin(t)
            py = r - r * inset * math.cos(t)
            if len(horizontal) == 1 and not on_top:
                # Flat against the side: wide along the tangent, thin along the normal.
                tangent_x = abs(math.cos(t))
                w_t = max(size[0], size[1])
                depth = min(size[0], size[1]) if min(size[0], size[1]) > 0 else w_t * 0.25
                sx_ = w_t * tangent_x + depth * (1 - tangent_x)
                sy_ = w_t * (1 - tangent_x) + depth * tangent_x
            else:
                sx_ = sy_ = max(size[0], size[1]) * 0.8
            return Box3((px - sx_ / 2, py - sy_ / 2, z0), (px + sx_ / 2, py + sy_ / 2, z1))
        # Only top and/or bottom: somewhere on the disc.
        s = max(size[0], size[1])
        reach = max(0.0, r * 0.85 - s / 2.0)
        rad = reach * math.sqrt(self.rng.random())
        ang = self.rng.uniform(0.0, 2 * math.pi)
        cx, cy = r + rad * math.cos(ang), r + rad * math.sin(ang)
        return Box3(
            (cx - size[0] / 2, cy - size[1] / 2, z0), (cx + size[0] / 2, cy + size[1] / 2, z1)
        )

    # -- fitting ---------------------------------------------------------------------

    def rects(self, box: Box3, views: tuple[str, ...]) -> dict[str, PixelRect] | None:
        out = {}
        for view in views:
            frame = self.frames[view]
            u0, v0, u1, v1 = project_box(view, self.dims, box)
            x0, y0 = frame.to_px(u0, v0)
            x1, y1 = frame.to_px(u1, v1)
            if x0 < 2 or y0 < 2 or x1 > frame.width - 2 or y1 > frame.height - 2:
                return None
            rect = frame.rect_px((u0, v0, u1, v1))
            if rect[2] - rect[0] < MIN_BOX or rect[3] - rect[1] < MIN_BOX:
                return None
            out[view] = rect
        return out

    def fits(self, rects: dict[str, PixelRect]) -> bool:
        for view, r in rects.items():
            for o in self.occupied[view]:
                if _overlap(r, o, GAP):
                    return False
        return True

    def commit(self, rects: dict[str, PixelRect]) -> None:
        for view, r in rects.items():
            self.occupied[view].append(r)

    def fit_box(
        self, label: str, faces: tuple[str, ...], w: float, h: float, attempts: int = 400
    ) -> tuple[Box3, dict[str, PixelRect]]:
        grow = self._min_growth(faces, w, h)
        w, h = w * grow, h * grow
        for attempt in range(attempts):
            if attempt and attempt % 40 == 0:
                w, h = w * 0.88, h * 0.88
            box = self.sample_box(faces, w, h)
            if self.body == "pistol" and not _on_pistol(self.dims, box):
                continue
            rects = self.rects(box, faces)
            if rects is not None and self.fits(rects):
                self.commit(rects)
                return box, rects
        raise LayoutError(f"cannot place {label} on {'/'.join(faces)}", label)

    def _min_growth(self, faces: tuple[str, ...], w: float, h: float) -> float:
        """Factor that makes the component at least MIN_BOX + 4 pixels in its main view."""
        frame = self.frames[faces[0]]
        smallest = min(w, h) * frame.scale
        need = MIN_BOX + 4
        return need / smallest if smallest < need else 1.0

    def place(self, name: str, spec: ComponentSpec, views: tuple[str, ...], machine: dict) -> Part:
        orientation = _orientation(name, spec, machine, self.rng)
        w, h = self.nominal_size(spec, views[0], orientation)
        box, _ = self.fit_box(name, views, w, h)
        style = Style(self._color(spec), self.rng.randrange(4))
        return Part(name, spec, views, box, style, orientation)

    def _color(self, spec: ComponentSpec) -> tuple[int, int, int]:
        return self.rng.choice(ACCENT_COLORS)


def _on_pistol(dims: Dims, box: Box3) -> bool:
    """The box's centre is on the barrel or the grip (with a margin for the surface)."""
    c = box.center
    for solid in pistol_solids(dims):
        if all(
            solid.lo[i] - 0.18 * dims[i] <= c[i] <= solid.hi[i] + 0.18 * dims[i] for i in range(3)
        ):
            return True
    return False


def _face_plane_axes(face: str) -> tuple[int, int]:
    if face in (FRONT, BACK):
        return 0, 2
    if face in (LEFT, RIGHT):
        return 1, 2
    return 0, 1


def _overlap(a: PixelRect, b: PixelRect, gap: int) -> bool:
    return a[0] < b[2] + gap and b[0] < a[2] + gap and a[1] < b[3] + gap and b[1] < a[3] + gap


# ----------------------------------------------------------------------------- dashboard


def _place_panel(
    placer: _Placer,
    catalog: Catalog,
    on_panel: list[str],
    machine: dict,
    rng: random.Random,
) -> tuple[Panel, list[Part]]:
    """The control panel on a face (sometimes on its top edge, so also seen from the top),
    its zoomed dashboard image, and the dashboard parts laid out on it."""
    faces = [
        catalog.components[c].faces[0]
        for c in catalog.components
        if catalog.components[c].on_dashboard
    ]
    face = max(sorted(set(faces)), key=faces.count) if faces else FRONT
    fw, fh = silhouette_size(face, placer.dims)
    n = max(1, len(on_panel))
    region_faces: tuple[str, ...] = (face,)
    if face in (FRONT, BACK, LEFT, RIGHT) and rng.random() < 0.35:
        region_faces = (face, TOP)
    w = fw * rng.uniform(0.3, 0.44) * (1.0 + 0.04 * max(0, n - 4))
    h = fh * rng.uniform(0.17, 0.27)
    w, h = min(w, fw * 0.75), min(h, fh * 0.4)
    try:
        box, rects = placer.fit_box("dashboard panel", region_faces, w, h)
    except LayoutError as exc:
        raise LayoutError(str(exc), None) from None

    u0, v0, u1, v1 = project_box(face, placer.dims, box)
    pad_u, pad_v = (u1 - u0) * 0.05, (v1 - v0) * 0.08
    pu0, pv0, pu1, pv1 = u0 - pad_u, v0 - pad_v, u1 + pad_u, v1 + pad_v
    width = rng.randint(1040, 1360)
    aspect = (pu1 - pu0) / (pv1 - pv0)
    height = max(440, min(980, round(width / aspect)))
    # Keep one scale on both axes: widen the shown plane rect along the short side.
    want = width / height
    if (pu1 - pu0) / (pv1 - pv0) < want:
        extra = (pv1 - pv0) * want - (pu1 - pu0)
        pu0, pu1 = pu0 - extra / 2, pu1 + extra / 2
    else:
        extra = (pu1 - pu0) / want - (pv1 - pv0)
        pv0, pv1 = pv0 - extra / 2, pv1 + extra / 2
    panel_stub = Panel(face, box, region_faces, width, height, (pu0, pv0, pu1, pv1), (0, 0, 1, 1))
    px0, py0 = panel_stub.plane_to_px(u0, v0)
    px1, py1 = panel_stub.plane_to_px(u1, v1)
    inner = (round(px0), round(py0), round(px1), round(py1))
    iw, ih = inner[2] - inner[0], inner[3] - inner[1]
    pad = round(min(iw, ih) * 0.07)
    disp_w = round(iw * rng.uniform(0.22, 0.3))
    disp_h = round(ih * rng.uniform(0.28, 0.36))
    dx = inner[0] + pad if rng.random() < 0.6 else inner[2] - pad - disp_w
    display = (dx, inner[1] + pad, dx + disp_w, inner[1] + pad + disp_h)
    occupied: list[PixelRect] = [display]
    parts: list[Part] = []
    base = min(iw, ih)
    for name in on_panel:
        spec = catalog.components[name]
        orientation = _orientation(name, spec, machine, rng)
        rect = _dashboard_rect(name, spec, orientation, base, inner, pad, occupied, rng)
        occupied.append(rect)
        pbox = _panel_part_box(placer.dims, face, panel_stub, rect)
        style = Style(rng.choice(ACCENT_COLORS), rng.randrange(4))
        parts.append(Part(name, spec, (DASHBOARD,), pbox, style, orientation, rect))
    panel = Panel(face, box, region_faces, width, height, (pu0, pv0, pu1, pv1), display)
    return panel, parts


def _dashboard_rect(
    name: str,
    spec: ComponentSpec,
    orientation: str,
    base: float,
    inner: PixelRect,
    pad: int,
    occupied: list[PixelRect],
    rng: random.Random,
) -> PixelRect:
    """Where a part goes on the dashboard image: sized by its kind and size, placed at random
    inside `inner` (less `pad`) clear of the `occupied` rects, shrunk a little every 50 tries."""
    frac = {"tiny": 0.3, "small": 0.34, "medium": 0.4, "large": 0.5}.get(spec.size, 0.34)
    s = base * frac * rng.uniform(0.9, 1.1)
    aspect = KIND_PROPORTION.get(spec.kind, 1.0)
    if spec.kind in ORIENTED_KINDS and orientation == "v":
        aspect = 1.0 / aspect
    if spec.kind == "button" and rng.random() < 0.5:
        aspect = 1.6
    pw, ph = s * math.sqrt(aspect), s / math.sqrt(aspect)
    for attempt in range(600):
        if attempt and attempt % 50 == 0:
            pw, ph = pw * 0.88, ph * 0.88
        x = rng.uniform(inner[0] + pad, max(inner[0] + pad, inner[2] - pad - pw))
        y = rng.uniform(inner[1] + pad, max(inner[1] + pad, inner[3] - pad - ph))
        cand = (round(x), round(y), round(x + pw), round(y + ph))
        if cand[2] > inner[2] or cand[3] > inner[3]:
            continue
        if cand[2] - cand[0] < MIN_BOX or cand[3] - cand[1] < MIN_BOX:
            continue
        if all(not _overlap(cand, o, 14) for o in occupied):
            return cand
    raise LayoutError(f"cannot place {name} on the dashboard", name)


def _panel_part_box(dims: Dims, face: str, panel: Panel, rect: PixelRect) -> Box3:
    """The 3D box, on the panel's face, of a part placed at `rect` on the dashboard image."""
    u0, v0 = panel.px_to_plane(rect[0], rect[1])
    u1, v1 = panel.px_to_plane(rect[2], rect[3])
    X, Y, Z = dims
    t = min(u1 - u0, v1 - v0) * 0.2
    normal = FACE_AXIS[face]
    surface = dims[normal] if FACE_IS_MAX[face] else 0.0
    n0, n1 = (
        (surface - t, surface + t * 0.5) if FACE_IS_MAX[face] else (surface - t * 0.5, surface + t)
    )
    # Invert the face view's projection (see the table in _geometry).
    if face == FRONT:
        return Box3((u0, n0, Z - v1), (u1, n1, Z - v0))
    if face == BACK:
        return Box3((X - u1, n0, Z - v1), (X - u0, n1, Z - v0))
    if face == LEFT:
        return Box3((n0, Y - u1, Z - v1), (n1, Y - u0, Z - v0))
    if face == RIGHT:
        return Box3((n0, u0, Z - v1), (n1, u1, Z - v0))
    if face == TOP:
        return Box3((u0, Y - v1, n0), (u1, Y - v0, n1))
    return Box3((u0, v0, n0), (u1, v1, n1))
