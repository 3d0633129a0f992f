"""Render a device's views with pillow: six orthographic views, two axonometric views and the
zoomed dashboard, all projections of the one 3D layout (`_layout`).

Deterministic: no clock, no randomness beyond the layout's, only PIL's built-in font. Drawing
happens at twice the size and is reduced with a 2x2 box filter, so every component (drawn on a
layer exactly the size of its bbox) stays inside its bbox in the final image.
"""

from __future__ import annotations

import io
import math

from PIL import Image, ImageDraw

from replay import AXONOMETRIC_VIEWS as AXO
from replay import DASHBOARD
from replay import ORTHOGRAPHIC_VIEWS as ORTHO
from replay.semantics import BACK, BOTTOM, FRONT, FRONT_TOP, LEFT, RIGHT, TOP

from ._geometry import (
    FACE_NORMALS,
    AxoFrame,
    Box3,
    Geometry,
    Part,
    PixelRect,
    project_box,
    silhouette_size,
)
from ._icons import draw_icon
from ._layout import body_outline_points, pistol_solids
from ._lettering import MIN_TEXT, centered_text, font, text_size
from ._motifs import MOTIFS
from ._motifs import PAINTERS as MOTIF_PAINTERS
from ._paint import PAINTERS, paint_part
from ._shapes import ROUND_KINDS, darker, ink_on

RENDER_VERSION = "render-v1"
"""Part of the image cache key: bump whenever the pictures change."""
SS = 2
"""Supersampling factor."""

# Kinds whose label is printed on the body next to them rather than on them.
_LABEL_BESIDE = frozenset(
    {
        "knob",
        "dial",
        "wheel",
        "crank",
        "lens",
        "slider",
        "switch",
        "rocker",
        "lever",
        "door",
        "port",
        "plug",
        "cable",
        "handle",
        "grip",
        "handset",
        "body",
        "head",
        "nozzle",
        "blade",
        "trigger",
        "basket",
        "tray",
        "drawer",
    }
)


def render_view(
    geometry: Geometry, view: str, *, omit: frozenset[str] = frozenset()
) -> Image.Image:
    """The view as an RGB image; `omit` leaves out the named components (for tests)."""
    if view in ORTHO:
        img = _ortho(geometry, view, omit)
    elif view in AXO:
        img = _axo(geometry, geometry.axo_frames[view], omit)
    elif view == DASHBOARD and geometry.panel is not None:
        img = _dashboard(geometry, omit)
    else:
        raise KeyError(f"{geometry.device_id} has no view {view!r}")
    return img.reduce(SS).convert("RGB")


def png_bytes(img: Image.Image) -> bytes:
    buf = io.BytesIO()
    img.save(buf, format="PNG", compress_level=6)
    return buf.getvalue()


def _scaled(rect: PixelRect) -> tuple[int, int, int, int]:
    return rect[0] * SS, rect[1] * SS, rect[2] * SS, rect[3] * SS


def _composite(
    canvas: Image.Image, part: Part, rect: PixelRect, geometry: Geometry, draw: bool = True
) -> bool:
    """Paint a part into its (scaled) bbox; returns whether its label is on it."""
    x0, y0, x1, y1 = _scaled(rect)
    layer, labelled = paint_part(part, (x1 - x0, y1 - y0), geometry.palette)
    if draw:
        canvas.alpha_composite(layer, (x0, y0))
    return labelled


def _overlaps(a, b) -> bool:
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


# ------------------------------------------------------------------------ orthographic


def _ortho(g: Geometry, view: str, omit: frozenset[str]) -> Image.Image:
    frame = g.frames[view]
    pal = g.palette
    W, H = frame.width * SS, frame.height * SS
    canvas = Image.new("RGBA", (W, H), pal.background + (255,))
    d = ImageDraw.Draw(canvas)
    a, b = silhouette_size(view, g.dims)
    x0, y0 = frame.to_px(0, 0)
    x1, y1 = frame.to_px(a, b)
    body = (x0 * SS, y0 * SS, x1 * SS, y1 * SS)
    bw, bh = body[2] - body[0], body[3] - body[1]
    if view not in (TOP, BOTTOM):
        d.ellipse(
            (body[0] - bw * 0.04, body[3] - bh * 0.02, body[2] + bw * 0.04, body[3] + bh * 0.05),
            fill=darker(pal.background, 0.12),
        )
    round_top = g.body == "cylinder" and view in (TOP, BOTTOM)
    outline = darker(pal.body, 0.4)
    lw = max(2, round(min(bw, bh) * 0.006))
    if g.body == "pistol" and view not in (TOP, BOTTOM):
        _pistol_silhouette(d, g, view, outline, lw)
    elif round_top:
        d.ellipse(body, fill=pal.body, outline=outline, width=lw * 2)
        inner = (body[0] + bw * 0.06, body[1] + bh * 0.06, body[2] - bw * 0.06, body[3] - bh * 0.06)
        d.ellipse(inner, outline=darker(pal.body, 0.12), width=lw)
    else:
        radius = min(bw, bh) * (0.12 if g.body == "cylinder" else 0.05)
        d.rounded_rectangle(body, radius=radius, fill=pal.body, outline=outline, width=lw * 2)
        _shade_sides(canvas, body, radius, g.body == "cylinder")
        d = ImageDraw.Draw(canvas)
        seam = body[1] + bh * 0.08
        d.line(
            (body[0] + bw * 0.03, seam, body[2] - bw * 0.03, seam),
            fill=darker(pal.body, 0.1),
            width=lw,
        )
    occupied = [_scaled(g.part_rect(p, view)) for p in g.parts if view in p.views]
    if g.panel is not None and view in g.panel.region_views:
        prect = frame.rect_px(project_box(view, g.dims, g.panel.box))
        occupied.append(_scaled(prect))
        _draw_panel_small(canvas, g, view, prect)
    _decorate(canvas, g, view, body, occupied)
    _body_print(canvas, g, view, body, occupied)
    beside = []
    for part in g.parts:
        if view in part.views:
            labelled = _composite(canvas, part, g.part_rect(part, view), g, part.name not in omit)
            if not labelled or part.spec.kind in _LABEL_BESIDE:
                beside.append(part)
    d = ImageDraw.Draw(canvas)
    ink = ink_on(g.palette.body)
    for part in beside:
        if part.spec.label:
            _label_near(
                d, part, _scaled(g.part_rect(part, view)), body, occupied, ink, g.palette.body
            )
    return canvas


def _pistol_silhouette(d, g: Geometry, view: str, outline, lw: int) -> None:
    """Barrel over grip, grown where a component sits off them: outline pass, then fill."""
    frame = g.frames[view]
    rects = []
    for solid in pistol_solids(g.dims):
        rects.append(_scaled(frame.rect_px(project_box(view, g.dims, solid))))
    pad = 0.05 * min(rects[0][2] - rects[0][0], rects[0][3] - rects[0][1])
    for part in g.parts:
        if view in part.views:
            x0, y0, x1, y1 = _scaled(g.part_rect(part, view))
            rects.append((x0 - pad, y0 - pad, x1 + pad, y1 + pad))
    radius = 0.2 * min(r[3] - r[1] for r in rects[:2])
    for r in rects:
        d.rounded_rectangle(
            r, radius=min(radius, (r[2] - r[0]) / 2, (r[3] - r[1]) / 2), fill=outline
        )
    for r in rects:
        inner = (r[0] + lw * 2, r[1] + lw * 2, r[2] - lw * 2, r[3] - lw * 2)
        if inner[2] > inner[0] and inner[3] > inner[1]:
            d.rounded_rectangle(
                inner,
                radius=min(radius, (inner[2] - inner[0]) / 2, (inner[3] - inner[1]) / 2),
                fill=g.palette.body,
            )


def _motifs(canvas: Image.Image, g: Geometry, view: str, body, occupied) -> None:
    """The category's recognisable details (cup bay, grille, clock face...) where free."""
    d = ImageDraw.Draw(canvas)
    x0, y0, x1, y1 = body
    bw, bh = x1 - x0, y1 - y0

    def text_fn(draw, r, text, ink) -> None:
        centered_text(draw, r, text, ink, int((r[3] - r[1]) * 0.6))

    for m_view, (fx0, fy0, fx1, fy1), painter in MOTIFS.get(g.category, ()):
        if m_view != view:
            continue
        cx, cy = x0 + bw * (fx0 + fx1) / 2, y0 + bh * (fy0 + fy1) / 2
        hw, hh = bw * (fx1 - fx0) / 2, bh * (fy1 - fy0) / 2
        for shrink in (1.0, 0.8, 0.62, 0.48):
            rect = (cx - hw * shrink, cy - hh * shrink, cx + hw * shrink, cy + hh * shrink)
            if all(not _overlaps(rect, o) for o in occupied):
                MOTIF_PAINTERS[painter](d, rect, g.palette.body, text_fn)
                occupied.append(rect)
                break


def _decorate(canvas: Image.Image, g: Geometry, view: str, body, occupied) -> None:
    """Non-interactive details that make a face recognisable: vents, feet, a rating plate."""
    _motifs(canvas, g, view, body, occupied)
    if g.body == "pistol":
        return
    d = ImageDraw.Draw(canvas)
    x0, y0, x1, y1 = body
    bw, bh = x1 - x0, y1 - y0
    dark = darker(g.palette.body, 0.3)
    free = lambda r: all(not _overlaps(r, o) for o in occupied)  # noqa: E731
    cyl = g.body == "cylinder"
    if view == BOTTOM or (cyl and view == TOP):
        if view == BOTTOM:
            r = min(bw, bh) * 0.05
            for fx, fy in ((0.12, 0.12), (0.88, 0.12), (0.12, 0.88), (0.88, 0.88)):
                if cyl:
                    fx, fy = 0.5 + (fx - 0.5) * 0.72, 0.5 + (fy - 0.5) * 0.72
                cx, cy = x0 + bw * fx, y0 + bh * fy
                rect = (cx - r, cy - r, cx + r, cy + r)
                if free(rect):
                    d.ellipse(rect, fill=(40, 40, 44))
        return
    if cyl:
        return
    if view in (BACK, LEFT, RIGHT):
        slot_w, slot_h = bw * 0.035, bh * 0.16
        top = y0 + bh * (0.14 if view == BACK else 0.1)
        start = x0 + bw * (0.55 if view != LEFT else 0.12)
        for k in range(7):
            sx = start + k * slot_w * 1.9
            rect = (sx, top, sx + slot_w, top + slot_h)
            if rect[2] < x1 - bw * 0.05 and free(rect):
                d.rounded_rectangle(rect, radius=slot_w * 0.45, fill=dark)
    if view == BACK:
        pw, ph = bw * 0.22, bh * 0.1
        for fx, fy in ((0.1, 0.75), (0.66, 0.75), (0.1, 0.45)):
            rect = (x0 + bw * fx, y0 + bh * fy, x0 + bw * fx + pw, y0 + bh * fy + ph)
            if rect[3] < y1 - bh * 0.04 and free(rect):
                d.rectangle(rect, fill=(236, 236, 232), outline=(120, 120, 120), width=2)
                centered_text(d, rect, f"{g.model_name}  220-240V~", (60, 60, 60), int(ph * 0.4))
                occupied.append(rect)
                break


def _shade_sides(canvas: Image.Image, body, radius: float, cylindrical: bool) -> None:
    """A light band at the top, and for cylinders darker flanks."""
    overlay = Image.new("RGBA", canvas.size, (0, 0, 0, 0))
    d = ImageDraw.Draw(overlay)
    x0, y0, x1, y1 = body
    bw = x1 - x0
    if cylindrical:
        for k in range(6):
            t = k / 6.0
            alpha = round(60 * (1 - t))
            d.rectangle(
                (x0 + bw * t * 0.12, y0, x0 + bw * (t + 1 / 6) * 0.12, y1), fill=(0, 0, 0, alpha)
            )
            d.rectangle(
                (x1 - bw * (t + 1 / 6) * 0.12, y0, x1 - bw * t * 0.12, y1), fill=(0, 0, 0, alpha)
            )
        d.rectangle((x0 + bw * 0.3, y0, x0 + bw * 0.4, y1), fill=(255, 255, 255, 28))
    else:
        d.rectangle((x0, y0, x1, y0 + (y1 - y0) * 0.06), fill=(255, 255, 255, 36))
    mask = Image.new("L", canvas.size, 0)
    inset = 3 * SS
    inner = (x0 + inset, y0 + inset, x1 - inset, y1 - inset)
    ImageDraw.Draw(mask).rounded_rectangle(inner, radius=max(1.0, radius - inset), fill=255)
    shaded = Image.alpha_composite(canvas, overlay)
    canvas.paste(shaded, (0, 0), mask)


def _body_print(canvas: Image.Image, g: Geometry, view: str, body, occupied) -> None:
    """The model name on the front (a printed logo) where nothing else is."""
    if view != FRONT:
        return
    d = ImageDraw.Draw(canvas)
    bw, bh = body[2] - body[0], body[3] - body[1]
    size = max(10, round(min(bw, bh) * 0.06))
    f = font(size)
    text = g.model_name
    x0, y0, x1, y1 = d.textbbox((0, 0), text, font=f)
    tw, th = x1 - x0, y1 - y0
    for fx, fy in ((0.5, 0.12), (0.15, 0.9), (0.5, 0.92), (0.85, 0.9), (0.15, 0.12), (0.85, 0.12)):
        cx = body[0] + bw * fx
        cy = body[1] + bh * fy
        rect = (cx - tw / 2 - 6, cy - th / 2 - 6, cx + tw / 2 + 6, cy + th / 2 + 6)
        if rect[0] < body[0] or rect[2] > body[2] or rect[1] < body[1] or rect[3] > body[3]:
            continue
        if any(_overlaps(rect, o) for o in occupied):
            continue
        d.text((cx, cy), text, font=f, fill=darker(g.palette.body, 0.35), anchor="mm")
        occupied.append(rect)
        return


def _label_near(d, part: Part, rect, bounds, occupied, ink, bg) -> None:
    """Print a part's label on the surface under (or over, or beside) it, where it does not
    cover anything; skipped when there is no room."""
    x0, y0, x1, y1 = rect
    w, h = x1 - x0, y1 - y0
    label = part.spec.label
    size = round(min(max(max(w, h) * 0.3, MIN_TEXT + 2), 22 * SS))
    lh = size * 1.35
    tw = lh if label.startswith("icon:") else text_size(d, label, font(size))[0] + 8
    half = max(w, tw) / 2 + 2
    cx = (x0 + x1) / 2
    cy = (y0 + y1) / 2
    candidates = (
        (cx - half, y1 + 4, cx + half, y1 + 4 + lh),
        (cx - half, y0 - 4 - lh, cx + half, y0 - 4),
        (x1 + 6, cy - lh / 2, x1 + 6 + tw, cy + lh / 2),
        (x0 - 6 - tw, cy - lh / 2, x0 - 6, cy + lh / 2),
    )
    for area in candidates:
        if area[0] < bounds[0] or area[2] > bounds[2] or area[1] < bounds[1] or area[3] > bounds[3]:
            continue
        if any(_overlaps(area, o) for o in occupied if o != rect):
            continue
        if label.startswith("icon:"):
            ax = (area[0] + area[2]) / 2
            ay = (area[1] + area[3]) / 2
            draw_icon(
                d,
                label[5:],
                (ax - lh / 2, ay - lh / 2, ax + lh / 2, ay + lh / 2),
                ink,
                bg,
                lambda text, a=area: centered_text(d, a, text, ink, size, MIN_TEXT),
            )
        elif not centered_text(d, area, label, ink, size, MIN_TEXT):
            continue
        occupied.append(area)
        return


def _draw_panel_small(canvas: Image.Image, g: Geometry, view: str, prect: PixelRect) -> None:
    """The control panel as seen from afar: its outline, display and tiny controls."""
    panel = g.panel
    assert panel is not None
    d = ImageDraw.Draw(canvas)
    x0, y0, x1, y1 = _scaled(prect)
    d.rounded_rectangle(
        (x0, y0, x1 - 1, y1 - 1),
        radius=min(x1 - x0, y1 - y0) * 0.08,
        fill=g.palette.panel,
        outline=darker(g.palette.panel, 0.4),
        width=2,
    )
    if view != panel.face:
        return
    frame = g.frames[view]

    def to_view(rect: PixelRect) -> tuple[float, float, float, float]:
        u0, v0 = panel.px_to_plane(rect[0], rect[1])
        u1, v1 = panel.px_to_plane(rect[2], rect[3])
        a0, b0 = frame.to_px(u0, v0)
        a1, b1 = frame.to_px(u1, v1)
        return a0 * SS, b0 * SS, a1 * SS, b1 * SS

    dx0, dy0, dx1, dy1 = to_view(panel.display)
    d.rectangle((dx0, dy0, dx1, dy1), fill=(28, 52, 40))
    for part in g.parts:
        if part.dash_rect is None:
            continue
        a0, b0, a1, b1 = (round(v) for v in to_view(part.dash_rect))
        if a1 - a0 < 2 or b1 - b0 < 2:
            continue
        layer, _ = paint_part(part, (a1 - a0, b1 - b0), g.palette)
        canvas.alpha_composite(layer, (a0, b0))


# ---------------------------------------------------------------------------- dashboard


def _dashboard(g: Geometry, omit: frozenset[str]) -> Image.Image:
    panel = g.panel
    assert panel is not None
    pal = g.palette
    W, H = panel.width * SS, panel.height * SS
    canvas = Image.new("RGBA", (W, H), pal.body + (255,))
    d = ImageDraw.Draw(canvas)
    u0, v0, u1, v1 = project_box(panel.face, g.dims, panel.box)
    px0, py0 = panel.plane_to_px(u0, v0)
    px1, py1 = panel.plane_to_px(u1, v1)
    inner = (px0 * SS, py0 * SS, px1 * SS, py1 * SS)
    d.rounded_rectangle(
        inner,
        radius=min(inner[2] - inner[0], inner[3] - inner[1]) * 0.06,
        fill=pal.panel,
        outline=darker(pal.panel, 0.5),
        width=4 * SS,
    )
    dx0, dy0, dx1, dy1 = _scaled(panel.display)
    d.rounded_rectangle(
        (dx0, dy0, dx1, dy1), radius=6 * SS, fill=(24, 46, 36), outline=(10, 20, 16), width=3 * SS
    )
    reading = f"{(len(g.device_id) * 7) % 12 + 1:02d}:{(len(g.model_name) * 13) % 60:02d}"
    centered_text(d, (dx0, dy0, dx1, dy1), reading, (120, 240, 160), int((dy1 - dy0) * 0.6))
    occupied = [(dx0, dy0, dx1, dy1)] + [_scaled(p.dash_rect) for p in g.parts if p.dash_rect]
    panel_ink = ink_on(pal.panel)
    beside = []
    for part in g.parts:
        if part.dash_rect is None:
            continue
        labelled = _composite(canvas, part, part.dash_rect, g, part.name not in omit)
        if not labelled or part.spec.kind in _LABEL_BESIDE:
            beside.append(part)
    d = ImageDraw.Draw(canvas)
    for part in beside:
        if part.spec.label:
            _label_near(d, part, _scaled(part.dash_rect), inner, occupied, panel_ink, pal.panel)
    return canvas


# -------------------------------------------------------------------------- axonometric


def _shade(color, normal, toward) -> tuple[int, int, int]:
    """Lambert shading with a light near the camera (slightly above and to the left)."""
    light = (toward[0] - 0.35, toward[1] - 0.2, toward[2] + 0.45)
    n = math.sqrt(sum(c * c for c in light))
    lam = max(0.0, sum(a * b for a, b in zip(normal, light, strict=True)) / n)
    k = 0.62 + 0.45 * lam
    return tuple(max(0, min(255, round(c * k))) for c in color)  # type: ignore[return-value]


_FACE_CORNERS = {
    FRONT: lambda lo, hi: [
        (lo[0], lo[1], lo[2]),
        (hi[0], lo[1], lo[2]),
        (hi[0], lo[1], hi[2]),
        (lo[0], lo[1], hi[2]),
    ],
    BACK: lambda lo, hi: [
        (lo[0], hi[1], lo[2]),
        (hi[0], hi[1], lo[2]),
        (hi[0], hi[1], hi[2]),
        (lo[0], hi[1], hi[2]),
    ],
    LEFT: lambda lo, hi: [
        (lo[0], lo[1], lo[2]),
        (lo[0], hi[1], lo[2]),
        (lo[0], hi[1], hi[2]),
        (lo[0], lo[1], hi[2]),
    ],
    RIGHT: lambda lo, hi: [
        (hi[0], lo[1], lo[2]),
        (hi[0], hi[1], lo[2]),
        (hi[0], hi[1], hi[2]),
        (hi[0], lo[1], hi[2]),
    ],
    TOP: lambda lo, hi: [
        (lo[0], lo[1], hi[2]),
        (hi[0], lo[1], hi[2]),
        (hi[0], hi[1], hi[2]),
        (lo[0], hi[1], hi[2]),
    ],
    BOTTOM: lambda lo, hi: [
        (lo[0], lo[1], lo[2]),
        (hi[0], lo[1], lo[2]),
        (hi[0], hi[1], lo[2]),
        (lo[0], hi[1], lo[2]),
    ],
}


def _face_circle(face: str, lo, hi, n: int = 28) -> list[tuple[float, float, float]]:
    """Points of the ellipse inscribed in a box face (for round controls)."""
    corners = _FACE_CORNERS[face](lo, hi)
    c = tuple(sum(p[i] for p in corners) / 4.0 for i in range(3))
    ea = tuple((corners[1][i] - corners[0][i]) / 2.0 for i in range(3))
    eb = tuple((corners[3][i] - corners[0][i]) / 2.0 for i in range(3))
    pts = []
    for k in range(n):
        t = 2 * math.pi * k / n
        pts.append(tuple(c[i] + math.cos(t) * ea[i] + math.sin(t) * eb[i] for i in range(3)))
    return pts  # type: ignore[return-value]


def _convex_hull(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    pts = sorted(set(points))
    if len(pts) <= 2:
        return pts

    def cross(o, a, b) -> float:
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: list = []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    upper: list = []
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return lower[:-1] + upper[:-1]


def _axo(g: Geometry, frame: AxoFrame, omit: frozenset[str]) -> Image.Image:
    pal = g.palette
    W, H = frame.width * SS, frame.height * SS
    canvas = Image.new("RGBA", (W, H), pal.background + (255,))
    d = ImageDraw.Draw(canvas)

    def px(p) -> tuple[float, float]:
        x, y = frame.to_px(p)
        return x * SS, y * SS

    X, Y, Z = g.dims
    # Floor shadow: the footprint projected.
    foot = [px((x, y, 0.0)) for x, y, _ in body_outline_points(g.body, g.dims) if _ == 0.0]
    if frame.view == FRONT_TOP:
        hull = _convex_hull(foot)
        if len(hull) >= 3:
            d.polygon(
                [(x + 10 * SS, y + 14 * SS) for x, y in hull], fill=darker(pal.background, 0.14)
            )
    outline = darker(pal.body, 0.45)
    if g.body == "cylinder":
        pts = [px(p) for p in body_outline_points(g.body, g.dims, 72)]
        d.polygon(
            _convex_hull(pts),
            fill=_shade(pal.body, (0.4, -0.9, 0.0), frame.toward),
            outline=outline,
        )
        cap_z = Z if frame.view == FRONT_TOP else 0.0
        cap = [px(p) for p in body_outline_points(g.body, g.dims, 72) if p[2] == cap_z]
        normal = (0.0, 0.0, 1.0 if cap_z else -1.0)
        d.polygon(_convex_hull(cap), fill=_shade(pal.body, normal, frame.toward), outline=outline)
    else:
        if g.body == "pistol":
            barrel, grip = pistol_solids(g.dims)
            boxes = [grip, barrel] if frame.view == FRONT_TOP else [barrel, grip]
        else:
            boxes = [Box3((0.0, 0.0, 0.0), (X, Y, Z))]
        for box in boxes:
            for face in sorted(FACE_NORMALS, key=lambda f: _face_depth(frame, box, f)):
                if not frame.sees(face):
                    continue
                poly = [px(p) for p in _FACE_CORNERS[face](box.lo, box.hi)]
                d.polygon(
                    poly,
                    fill=_shade(pal.body, FACE_NORMALS[face], frame.toward),
                    outline=outline,
                    width=2 * SS,
                )
    items: list[tuple[float, Part | None]] = []
    for part in g.parts:
        if part.name in omit:
            continue
        faces = _part_faces(part, g)
        if any(frame.sees(f) for f in faces):
            items.append((frame.depth(part.box.center), part))
    if g.panel is not None and any(frame.sees(f) for f in g.panel.region_views):
        items.append((frame.depth(g.panel.box.center) - 1e-6, None))
    items.sort(key=lambda it: it[0])
    for _, part in items:
        if part is None:
            _axo_box(
                d,
                frame,
                g.panel.box,
                (g.panel.face,) + g.panel.region_views,
                g.palette.panel,
                False,
                px,
            )  # type: ignore[union-attr]
            continue
        color = _axo_color(part, g)
        _axo_box(d, frame, part.box, _part_faces(part, g), color, part.spec.kind in ROUND_KINDS, px)
    return canvas


def _face_depth(frame: AxoFrame, box: Box3, face: str) -> float:
    pts = _FACE_CORNERS[face](box.lo, box.hi)
    return sum(frame.depth(p) for p in pts) / 4.0


def _part_faces(part: Part, g: Geometry) -> tuple[str, ...]:
    if part.views == (DASHBOARD,):
        return (g.panel.face,) if g.panel is not None else ()
    return part.views


def _axo_color(part: Part, g: Geometry) -> tuple[int, int, int]:
    kind = part.spec.kind
    if kind in ("door", "lid", "cover", "drawer", "basket", "tray", "body"):
        return darker(g.palette.body, 0.12)
    if kind in ("knob", "dial", "wheel", "crank", "port", "plug", "cable", "handle", "grip"):
        return (60, 62, 68)
    if kind == "tank":
        return (150, 190, 220)
    if kind in ("head", "blade", "platform"):
        return (200, 202, 208)
    return part.style.color


def _axo_box(d, frame: AxoFrame, box: Box3, faces, color, round_top: bool, px) -> None:
    """A component in the axonometric view: its outer face on each body face it sits on
    (round for knobs and dials), like a decal on the body's surface."""
    for face in sorted(faces, key=lambda f: _face_depth(frame, box, f)):
        if face not in FACE_NORMALS or not frame.sees(face):
            continue
        shade = _shade(color, FACE_NORMALS[face], frame.toward)
        if round_top:
            pts = [px(p) for p in _face_circle(face, box.lo, box.hi)]
        else:
            pts = [px(p) for p in _FACE_CORNERS[face](box.lo, box.hi)]
        d.polygon(pts, fill=shade, outline=darker(shade, 0.45))


__all__ = ["PAINTERS", "RENDER_VERSION", "png_bytes", "render_view"]
