"""How each kind of component is drawn: a painter per kind, working inside the component's
own box (the renderer gives it a layer exactly the size of its bbox, so nothing a painter
draws can leave the bbox)."""

from __future__ import annotations

import functools
import math
from collections.abc import Callable

from PIL import Image, ImageDraw

from ._geometry import Palette, Part
from ._icons import draw_icon
from ._lettering import MIN_TEXT, centered_text, font
from ._shapes import darker, ink_on, lighter
from ._strokes import radial_ticks

RGB = tuple[int, int, int]


@functools.cache
def _label(
    d: ImageDraw.ImageDraw,
    part: Part,
    box: tuple[float, float, float, float],
    ink,
    bg,
) -> bool:
    """The part's label (text or icon) centred in `box`; False when it does not fit legibly
    (the renderer then prints it on the body beside the part)."""
    label = part.spec.label
    if not label:
        return True
    if label.startswith("icon:"):
        x0, y0, x1, y1 = box
        s = min(x1 - x0, y1 - y0)
        if s < MIN_TEXT:
            return False
        cx, cy = (x0 + x1) / 2.0, (y0 + y1) / 2.0
        sq = (cx - s / 2, cy - s / 2, cx + s / 2, cy + s / 2)
        draw_icon(
            d,
            label[5:],
            sq,
            ink,
            bg,
            lambda text: centered_text(d, box, text, ink, int(s * 0.4), MIN_TEXT),
        )
        return True
    return centered_text(d, box, label, ink, int((box[3] - box[1]) * 0.42), MIN_TEXT)


# ------------------------------------------------------------------------- the painters
# Each takes (draw, w, h, part, palette) and draws in [0, w) x [0, h).


def _inset(w: int, h: int, k: float) -> tuple[float, float, float, float]:
    m = min(w, h) * k
    return (m, m, w - 1 - m, h - 1 - m)


def paint_button(d, w, h, part: Part, pal: Palette) -> None:
    color = part.style.color
    edge = darker(color, 0.35)
    box = _inset(w, h, 0.04)
    s = min(w, h)
    variant = part.style.variant
    if variant == 1 and 0.7 < w / h < 1.4:
        d.ellipse(box, fill=edge)
        d.ellipse(_inset(w, h, 0.1), fill=color)
        d.arc(
            _inset(w, h, 0.16),
            start=200,
            end=300,
            fill=lighter(color, 0.5),
            width=max(1, round(s * 0.05)),
        )
    else:
        radius = s * (0.45 if variant == 2 else 0.18)
        d.rounded_rectangle(box, radius=radius, fill=edge)
        inner = (box[0] + s * 0.06, box[1] + s * 0.04, box[2] - s * 0.06, box[3] - s * 0.1)
        d.rounded_rectangle(inner, radius=radius * 0.8, fill=color)
    return _label(d, part, _inset(w, h, 0.18), ink_on(color), color)


def paint_touch_pad(d, w, h, part: Part, pal: Palette) -> None:
    base = (34, 38, 46)
    glow = part.style.color
    d.rounded_rectangle(
        _inset(w, h, 0.03),
        radius=min(w, h) * 0.2,
        fill=base,
        outline=glow,
        width=max(2, round(min(w, h) * 0.05)),
    )
    return _label(d, part, _inset(w, h, 0.2), lighter(glow, 0.4), base)


def paint_key(d, w, h, part: Part, pal: Palette) -> None:
    color = lighter(part.style.color, 0.55)
    d.rounded_rectangle(_inset(w, h, 0.03), radius=min(w, h) * 0.15, fill=darker(color, 0.35))
    d.rounded_rectangle(
        (w * 0.08, h * 0.06, w * 0.92, h * 0.8), radius=min(w, h) * 0.12, fill=color
    )
    return _label(d, part, (w * 0.1, h * 0.1, w * 0.9, h * 0.76), ink_on(color), color)


def paint_trigger(d, w, h, part: Part, pal: Palette) -> None:
    color = darker(part.style.color, 0.1)
    pts = [
        (w * 0.2, h * 0.02),
        (w * 0.95, h * 0.02),
        (w * 0.85, h * 0.45),
        (w * 0.6, h * 0.98),
        (w * 0.25, h * 0.9),
        (w * 0.45, h * 0.45),
    ]
    d.polygon(pts, fill=color, outline=darker(color, 0.4))
    for k in range(3):
        y = h * (0.3 + 0.18 * k)
        d.line(
            (w * 0.45, y, w * 0.75, y - h * 0.05),
            fill=darker(color, 0.3),
            width=max(1, round(w * 0.04)),
        )


def _round_base(d, w, h, color) -> tuple[float, float, float]:
    s = min(w, h)
    cx, cy = w / 2.0, h / 2.0
    return cx, cy, s


def paint_knob(d, w, h, part: Part, pal: Palette) -> None:
    cx, cy, s = _round_base(d, w, h, part.style.color)
    body = (52, 54, 60) if part.style.variant % 2 == 0 else (214, 214, 210)
    ink = ink_on(pal.body)
    r_out = s * 0.48
    # Ticks around the knob.
    ticks = (math.radians(-225 + k * 33.75) for k in range(9))
    radial_ticks(d, cx, cy, r_out, 0.84, 1, ticks, fill=ink, width=max(1, round(s * 0.025)))
    r = s * 0.36
    d.ellipse((cx - r, cy - r, cx + r, cy + r), fill=darker(body, 0.3))
    r2 = r * 0.88
    d.ellipse((cx - r2, cy - r2, cx + r2, cy + r2), fill=body)
    # Grip ridges and the pointer.
    ridges = (math.radians(k * 30) for k in range(12))
    radial_ticks(
        d, cx, cy, r2, 0.8, 1, ridges, fill=darker(body, 0.25), width=max(1, round(s * 0.02))
    )
    a = math.radians(-90 + 35 * (part.style.variant - 1.5))
    d.line(
        (cx, cy, cx + math.cos(a) * r2 * 0.85, cy + math.sin(a) * r2 * 0.85),
        fill=part.style.color,
        width=max(2, round(s * 0.06)),
    )


def paint_dial(d, w, h, part: Part, pal: Palette) -> None:
    cx, cy, s = _round_base(d, w, h, part.style.color)
    face = (244, 242, 236)
    r = s * 0.48
    d.ellipse((cx - r, cy - r, cx + r, cy + r), fill=(70, 72, 78))
    r2 = r * 0.9
    d.ellipse((cx - r2, cy - r2, cx + r2, cy + r2), fill=face)
    f = font(max(8, round(s * 0.11)))
    for k in range(6):
        a = math.radians(-210 + k * 48)
        px, py = cx + math.cos(a) * r2 * 0.72, cy + math.sin(a) * r2 * 0.72
        d.text((px, py), str(k * 10 if k else 0), font=f, fill=(30, 30, 30), anchor="mm")
    d.ellipse((cx - r2 * 0.32, cy - r2 * 0.32, cx + r2 * 0.32, cy + r2 * 0.32), fill=(60, 62, 68))
    a = math.radians(-210 + 48 * (part.style.variant + 1))
    d.line(
        (cx, cy, cx + math.cos(a) * r2 * 0.55, cy + math.sin(a) * r2 * 0.55),
        fill=(220, 50, 40),
        width=max(2, round(s * 0.05)),
    )


def paint_wheel(d, w, h, part: Part, pal: Palette) -> None:
    color = (70, 72, 80)
    if max(w, h) > 1.6 * min(w, h):  # seen edge-on: a knurled strip
        d.rounded_rectangle(_inset(w, h, 0.04), radius=min(w, h) * 0.3, fill=color)
        n = 9
        horizontal = w > h
        for k in range(1, n):
            t = k / n
            if horizontal:
                d.line(
                    (w * t, h * 0.12, w * t, h * 0.88),
                    fill=lighter(color, 0.35),
                    width=max(1, round(w * 0.02)),
                )
            else:
                d.line(
                    (w * 0.12, h * t, w * 0.88, h * t),
                    fill=lighter(color, 0.35),
                    width=max(1, round(h * 0.02)),
                )
        return
    cx, cy, s = _round_base(d, w, h, color)
    r = s * 0.47
    d.ellipse((cx - r, cy - r, cx + r, cy + r), fill=color)
    ridges = (math.radians(k * 15) for k in range(24))
    radial_ticks(
        d, cx, cy, r, 0.8, 1, ridges, fill=lighter(color, 0.4), width=max(1, round(s * 0.03))
    )
    d.ellipse((cx - r * 0.3, cy - r * 0.3, cx + r * 0.3, cy + r * 0.3), fill=lighter(color, 0.2))


def paint_ring(d, w, h, part: Part, pal: Palette) -> None:
    color = darker(part.style.color, 0.2)
    if max(w, h) > 1.4 * min(w, h):  # a band around the body
        d.rectangle(_inset(w, h, 0.02), fill=color)
        horizontal = w > h
        n = 14
        for k in range(1, n):
            t = k / n
            if horizontal:
                d.line((w * t, 0, w * t, h), fill=darker(color, 0.3), width=max(1, round(w * 0.01)))
            else:
                d.line((0, h * t, w, h * t), fill=darker(color, 0.3), width=max(1, round(h * 0.01)))
    else:
        cx, cy, s = _round_base(d, w, h, color)
        r = s * 0.48
        d.ellipse((cx - r, cy - r, cx + r, cy + r), fill=color)
        d.ellipse(
            (cx - r * 0.62, cy - r * 0.62, cx + r * 0.62, cy + r * 0.62),
            fill=darker(pal.body, 0.05),
        )
    return _label(d, part, _inset(w, h, 0.15), ink_on(color), color)


def paint_crank(d, w, h, part: Part, pal: Palette) -> None:
    cx, cy, s = _round_base(d, w, h, part.style.color)
    color = (80, 80, 86)
    r = s * 0.2
    d.ellipse((cx - r, cy - r, cx + r, cy + r), fill=color)
    d.line((cx, cy, cx + s * 0.32, cy - s * 0.28), fill=color, width=max(2, round(s * 0.1)))
    k = s * 0.1
    d.ellipse(
        (cx + s * 0.32 - k, cy - s * 0.28 - k, cx + s * 0.32 + k, cy - s * 0.28 + k),
        fill=part.style.color,
    )


def paint_lens(d, w, h, part: Part, pal: Palette) -> None:
    cx, cy, s = _round_base(d, w, h, part.style.color)
    for frac, col in (
        (0.48, (40, 40, 44)),
        (0.4, (90, 92, 98)),
        (0.32, (20, 24, 36)),
        (0.22, (30, 44, 80)),
    ):
        r = s * frac
        d.ellipse((cx - r, cy - r, cx + r, cy + r), fill=col)
    d.ellipse((cx - s * 0.16, cy - s * 0.18, cx - s * 0.04, cy - s * 0.06), fill=(200, 210, 240))


def paint_slider(d, w, h, part: Part, pal: Palette) -> None:
    horizontal = w >= h
    track = darker(pal.body, 0.45)
    thumb = part.style.color
    if horizontal:
        d.rounded_rectangle((w * 0.02, h * 0.38, w * 0.98, h * 0.62), radius=h * 0.1, fill=track)
        x = w * (0.08 + 0.28 * (part.style.variant % 3))
        d.rounded_rectangle(
            (x, h * 0.06, x + w * 0.3, h * 0.94),
            radius=h * 0.15,
            fill=thumb,
            outline=darker(thumb, 0.4),
            width=max(1, round(h * 0.05)),
        )
        for k in range(3):
            lx = x + w * (0.09 + 0.06 * k)
            d.line(
                (lx, h * 0.25, lx, h * 0.75),
                fill=darker(thumb, 0.35),
                width=max(1, round(w * 0.012)),
            )
    else:
        d.rounded_rectangle((w * 0.38, h * 0.02, w * 0.62, h * 0.98), radius=w * 0.1, fill=track)
        y = h * (0.08 + 0.28 * (part.style.variant % 3))
        d.rounded_rectangle(
            (w * 0.06, y, w * 0.94, y + h * 0.3),
            radius=w * 0.15,
            fill=thumb,
            outline=darker(thumb, 0.4),
            width=max(1, round(w * 0.05)),
        )
        for k in range(3):
            ly = y + h * (0.09 + 0.06 * k)
            d.line(
                (w * 0.25, ly, w * 0.75, ly),
                fill=darker(thumb, 0.35),
                width=max(1, round(h * 0.012)),
            )


def paint_switch(d, w, h, part: Part, pal: Palette) -> None:
    frame = (50, 52, 58)
    d.rounded_rectangle(_inset(w, h, 0.03), radius=min(w, h) * 0.12, fill=frame)
    color = part.style.color
    tall = h >= w
    if tall:
        d.rounded_rectangle(
            (w * 0.14, h * 0.08, w * 0.86, h * 0.92), radius=min(w, h) * 0.1, fill=color
        )
        d.rectangle((w * 0.14, h * 0.5, w * 0.86, h * 0.92), fill=darker(color, 0.25))
        centered_text(d, (w * 0.14, h * 0.1, w * 0.86, h * 0.48), "I", ink_on(color), int(h * 0.3))
        centered_text(
            d,
            (w * 0.14, h * 0.52, w * 0.86, h * 0.9),
            "O",
            ink_on(darker(color, 0.25)),
            int(h * 0.3),
        )
    else:
        d.rounded_rectangle(
            (w * 0.08, h * 0.14, w * 0.92, h * 0.86), radius=min(w, h) * 0.1, fill=color
        )
        d.rectangle((w * 0.5, h * 0.14, w * 0.92, h * 0.86), fill=darker(color, 0.25))
        centered_text(d, (w * 0.1, h * 0.14, w * 0.48, h * 0.86), "I", ink_on(color), int(h * 0.5))
        centered_text(
            d,
            (w * 0.52, h * 0.14, w * 0.9, h * 0.86),
            "O",
            ink_on(darker(color, 0.25)),
            int(h * 0.5),
        )


def paint_lever(d, w, h, part: Part, pal: Palette) -> None:
    color = (90, 92, 98)
    if w >= h:
        d.rounded_rectangle((w * 0.02, h * 0.3, w * 0.98, h * 0.7), radius=h * 0.2, fill=color)
        d.ellipse((w * 0.8, h * 0.05, w * 0.98, h * 0.95), fill=part.style.color)
    else:
        d.rounded_rectangle((w * 0.3, h * 0.02, w * 0.7, h * 0.98), radius=w * 0.2, fill=color)
        d.ellipse((w * 0.05, h * 0.02, w * 0.95, h * 0.2), fill=part.style.color)


def paint_door(d, w, h, part: Part, pal: Palette) -> None:
    frame = darker(pal.body, 0.12)
    d.rounded_rectangle(
        _inset(w, h, 0.005),
        radius=min(w, h) * 0.04,
        fill=frame,
        outline=darker(pal.body, 0.45),
        width=max(2, round(min(w, h) * 0.012)),
    )
    glass = (40, 46, 56)
    gx0, gy0, gx1, gy1 = w * 0.1, h * 0.12, w * 0.9, h * 0.85
    d.rounded_rectangle((gx0, gy0, gx1, gy1), radius=min(w, h) * 0.05, fill=glass)
    # Mesh dots and a reflection.
    step = max(4, round(min(w, h) * 0.04))
    for yy in range(round(gy0) + step, round(gy1), step):
        for xx in range(round(gx0) + step, round(gx1), step):
            d.point((xx, yy), fill=(70, 78, 90))
    d.polygon(
        [
            (gx0 + (gx1 - gx0) * 0.1, gy0),
            (gx0 + (gx1 - gx0) * 0.3, gy0),
            (gx0, gy0 + (gy1 - gy0) * 0.5),
            (gx0, gy0 + (gy1 - gy0) * 0.25),
        ],
        fill=(90, 100, 118),
    )
    # A pull handle along the edge away from the hinge.
    hx = w * (0.93 if part.style.variant % 2 == 0 else 0.03)
    d.rounded_rectangle(
        (hx, h * 0.25, hx + w * 0.04, h * 0.75),
        radius=w * 0.02,
        fill=(190, 192, 198),
        outline=(90, 92, 98),
    )


def paint_lid(d, w, h, part: Part, pal: Palette) -> None:
    color = lighter(pal.body, 0.08) if sum(pal.body) < 380 else darker(pal.body, 0.06)
    d.rounded_rectangle(
        _inset(w, h, 0.01),
        radius=min(w, h) * 0.12,
        fill=color,
        outline=darker(pal.body, 0.45),
        width=max(2, round(min(w, h) * 0.025)),
    )
    d.rounded_rectangle(
        (w * 0.38, h * 0.8, w * 0.62, h * 0.94), radius=min(w, h) * 0.04, fill=darker(color, 0.3)
    )
    return _label(d, part, (w * 0.2, h * 0.25, w * 0.8, h * 0.7), ink_on(color), color)


def paint_drawer(d, w, h, part: Part, pal: Palette) -> None:
    color = darker(pal.body, 0.08)
    d.rounded_rectangle(
        _inset(w, h, 0.01),
        radius=min(w, h) * 0.08,
        fill=color,
        outline=darker(pal.body, 0.45),
        width=max(2, round(min(w, h) * 0.02)),
    )
    d.rounded_rectangle(
        (w * 0.3, h * 0.35, w * 0.7, h * 0.55), radius=min(w, h) * 0.06, fill=darker(color, 0.45)
    )
    return _label(d, part, (w * 0.2, h * 0.62, w * 0.8, h * 0.92), ink_on(color), color)


def paint_tank(d, w, h, part: Part, pal: Palette) -> None:
    d.rounded_rectangle(
        _inset(w, h, 0.01),
        radius=min(w, h) * 0.1,
        fill=(190, 214, 232),
        outline=(90, 120, 150),
        width=max(2, round(min(w, h) * 0.02)),
    )
    d.rectangle((w * 0.06, h * 0.45, w * 0.94, h * 0.94), fill=(120, 170, 215))
    for k in range(4):
        y = h * (0.2 + 0.15 * k)
        d.line((w * 0.78, y, w * 0.92, y), fill=(60, 90, 120), width=max(1, round(h * 0.01)))
    return _label(d, part, (w * 0.15, h * 0.1, w * 0.75, h * 0.4), (40, 60, 90), (190, 214, 232))


def paint_cap(d, w, h, part: Part, pal: Palette) -> None:
    color = darker(part.style.color, 0.15)
    if max(w, h) > 1.4 * min(w, h):
        d.rounded_rectangle(_inset(w, h, 0.02), radius=min(w, h) * 0.2, fill=color)
        horizontal = w > h
        for k in range(1, 10):
            t = k / 10
            if horizontal:
                d.line(
                    (w * t, h * 0.1, w * t, h * 0.9),
                    fill=darker(color, 0.3),
                    width=max(1, round(w * 0.01)),
                )
            else:
                d.line(
                    (w * 0.1, h * t, w * 0.9, h * t),
                    fill=darker(color, 0.3),
                    width=max(1, round(h * 0.01)),
                )
    else:
        cx, cy, s = _round_base(d, w, h, color)
        r = s * 0.47
        d.ellipse((cx - r, cy - r, cx + r, cy + r), fill=color)
        ridges = (math.radians(k * 22.5) for k in range(16))
        radial_ticks(
            d, cx, cy, r, 0.75, 1, ridges, fill=darker(color, 0.35), width=max(1, round(s * 0.03))
        )
    return _label(d, part, _inset(w, h, 0.25), ink_on(color), color)


def paint_head(d, w, h, part: Part, pal: Palette) -> None:
    color = (200, 202, 208)
    d.rounded_rectangle(_inset(w, h, 0.02), radius=min(w, h) * 0.3, fill=(120, 122, 130))
    d.rounded_rectangle(_inset(w, h, 0.1), radius=min(w, h) * 0.25, fill=color)
    step = max(3, round(min(w, h) * 0.08))
    for yy in range(round(h * 0.18), round(h * 0.82), step):
        d.line((w * 0.18, yy, w * 0.82, yy), fill=(150, 152, 160), width=1)


def paint_nozzle(d, w, h, part: Part, pal: Palette) -> None:
    color = (60, 62, 68)
    d.polygon(
        [(w * 0.15, h * 0.05), (w * 0.85, h * 0.05), (w * 0.98, h * 0.95), (w * 0.02, h * 0.95)],
        fill=color,
    )
    d.rectangle((w * 0.2, h * 0.4, w * 0.8, h * 0.5), fill=lighter(color, 0.3))


def paint_attachment(d, w, h, part: Part, pal: Palette) -> None:
    color = lighter(part.style.color, 0.3)
    d.rounded_rectangle(
        _inset(w, h, 0.03),
        radius=min(w, h) * 0.2,
        fill=color,
        outline=darker(color, 0.4),
        width=max(1, round(min(w, h) * 0.03)),
    )
    n = 7
    for k in range(n):
        x = w * (0.15 + 0.7 * k / (n - 1))
        d.line((x, h * 0.15, x, h * 0.5), fill=darker(color, 0.45), width=max(1, round(w * 0.025)))
    return _label(d, part, (w * 0.1, h * 0.55, w * 0.9, h * 0.9), ink_on(color), color)


def paint_port(d, w, h, part: Part, pal: Palette) -> None:
    d.rounded_rectangle(_inset(w, h, 0.03), radius=min(w, h) * 0.2, fill=(30, 30, 34))
    if part.spec.kind == "port" and "usb" in part.spec.label.lower():
        d.rounded_rectangle(
            (w * 0.22, h * 0.35, w * 0.78, h * 0.65), radius=h * 0.12, fill=(150, 150, 158)
        )
    else:
        for fx in (0.33, 0.67):
            d.rounded_rectangle(
                (w * fx - w * 0.06, h * 0.3, w * fx + w * 0.06, h * 0.7),
                radius=w * 0.03,
                fill=(140, 140, 148),
            )


def paint_plug(d, w, h, part: Part, pal: Palette) -> None:
    body = (36, 36, 40)
    tall = h >= w
    if tall:
        d.rounded_rectangle(
            (w * 0.15, h * 0.02, w * 0.85, h * 0.55), radius=min(w, h) * 0.15, fill=body
        )
        d.rectangle((w * 0.42, h * 0.55, w * 0.58, h * 0.98), fill=body)
        for fx in (0.35, 0.65):
            d.rectangle(
                (w * fx - w * 0.04, h * 0.1, w * fx + w * 0.04, h * 0.25), fill=(180, 170, 120)
            )
    else:
        d.rounded_rectangle(
            (w * 0.02, h * 0.15, w * 0.55, h * 0.85), radius=min(w, h) * 0.15, fill=body
        )
        d.rectangle((w * 0.55, h * 0.42, w * 0.98, h * 0.58), fill=body)
        for fy in (0.35, 0.65):
            d.rectangle(
                (w * 0.1, h * fy - h * 0.04, w * 0.25, h * fy + h * 0.04), fill=(180, 170, 120)
            )


def paint_cable(d, w, h, part: Part, pal: Palette) -> None:
    color = (40, 40, 44)
    pts = []
    for k in range(40):
        t = k / 39
        pts.append((w * (0.1 + 0.8 * t), h * (0.5 + 0.3 * math.sin(t * 4 * math.pi))))
    d.line(pts, fill=color, width=max(2, round(min(w, h) * 0.1)))
    d.rounded_rectangle(
        (w * 0.72, h * 0.25, w * 0.98, h * 0.75), radius=min(w, h) * 0.1, fill=color
    )


def paint_handle(d, w, h, part: Part, pal: Palette) -> None:
    color = (70, 72, 78) if sum(pal.body) > 380 else (200, 200, 204)
    if w >= h:
        d.rounded_rectangle((w * 0.02, h * 0.2, w * 0.98, h * 0.8), radius=h * 0.3, fill=color)
        d.rectangle((w * 0.08, h * 0.02, w * 0.16, h * 0.98), fill=darker(color, 0.3))
        d.rectangle((w * 0.84, h * 0.02, w * 0.92, h * 0.98), fill=darker(color, 0.3))
    else:
        d.rounded_rectangle((w * 0.2, h * 0.02, w * 0.8, h * 0.98), radius=w * 0.3, fill=color)
        d.rectangle((w * 0.02, h * 0.08, w * 0.98, h * 0.16), fill=darker(color, 0.3))
        d.rectangle((w * 0.02, h * 0.84, w * 0.98, h * 0.92), fill=darker(color, 0.3))


def paint_grip(d, w, h, part: Part, pal: Palette) -> None:
    color = (54, 56, 60)
    d.rounded_rectangle(_inset(w, h, 0.02), radius=min(w, h) * 0.3, fill=color)
    step = max(4, round(min(w, h) * 0.12))
    if h >= w:
        for yy in range(round(h * 0.1), round(h * 0.9), step):
            d.line(
                (w * 0.2, yy, w * 0.8, yy),
                fill=lighter(color, 0.25),
                width=max(1, round(step * 0.3)),
            )
    else:
        for xx in range(round(w * 0.1), round(w * 0.9), step):
            d.line(
                (xx, h * 0.2, xx, h * 0.8),
                fill=lighter(color, 0.25),
                width=max(1, round(step * 0.3)),
            )


def paint_handset(d, w, h, part: Part, pal: Palette) -> None:
    color = darker(pal.body, 0.15)
    if w >= h:
        d.rounded_rectangle((w * 0.15, h * 0.3, w * 0.85, h * 0.7), radius=h * 0.2, fill=color)
        d.rounded_rectangle((w * 0.02, h * 0.05, w * 0.28, h * 0.95), radius=h * 0.3, fill=color)
        d.rounded_rectangle((w * 0.72, h * 0.05, w * 0.98, h * 0.95), radius=h * 0.3, fill=color)
        for fx in (0.15, 0.85):
            for k in range(3):
                d.ellipse(
                    (
                        w * fx - 3 + (k - 1) * w * 0.04,
                        h * 0.5 - 3,
                        w * fx + 3 + (k - 1) * w * 0.04,
                        h * 0.5 + 3,
                    ),
                    fill=darker(color, 0.5),
                )
    else:
        d.rounded_rectangle((w * 0.3, h * 0.15, w * 0.7, h * 0.85), radius=w * 0.2, fill=color)
        d.rounded_rectangle((w * 0.05, h * 0.02, w * 0.95, h * 0.28), radius=w * 0.3, fill=color)
        d.rounded_rectangle((w * 0.05, h * 0.72, w * 0.95, h * 0.98), radius=w * 0.3, fill=color)


def paint_body(d, w, h, part: Part, pal: Palette) -> None:
    color = darker(pal.body, 0.1)
    d.rounded_rectangle(
        _inset(w, h, 0.01),
        radius=min(w, h) * 0.25,
        fill=color,
        outline=darker(pal.body, 0.4),
        width=max(2, round(min(w, h) * 0.02)),
    )
    step = max(5, round(min(w, h) * 0.08))
    for yy in range(round(h * 0.1), round(h * 0.9), step):
        d.line((w * 0.15, yy, w * 0.85, yy), fill=darker(color, 0.15), width=1)


def paint_platform(d, w, h, part: Part, pal: Palette) -> None:
    d.rounded_rectangle(
        _inset(w, h, 0.01),
        radius=min(w, h) * 0.06,
        fill=(220, 228, 232),
        outline=(150, 160, 168),
        width=max(2, round(min(w, h) * 0.012)),
    )
    d.polygon(
        [(w * 0.05, h * 0.05), (w * 0.3, h * 0.05), (w * 0.05, h * 0.4)], fill=(240, 244, 246)
    )
    return _label(d, part, (w * 0.25, h * 0.4, w * 0.75, h * 0.6), (60, 70, 80), (220, 228, 232))


def paint_blade(d, w, h, part: Part, pal: Palette) -> None:
    d.rectangle(_inset(w, h, 0.02), fill=(190, 194, 200))
    n = 10
    for k in range(1, n):
        x = w * k / n
        d.line((x, h * 0.1, x, h * 0.9), fill=(120, 124, 130), width=max(1, round(w * 0.01)))


PAINTERS: dict[str, Callable] = {
    "button": paint_button,
    "touch_pad": paint_touch_pad,
    "key": paint_key,
    "trigger": paint_trigger,
    "shutter_button": paint_button,
    "knob": paint_knob,
    "dial": paint_dial,
    "wheel": paint_wheel,
    "ring": paint_ring,
    "crank": paint_crank,
    "lens": paint_lens,
    "slider": paint_slider,
    "switch": paint_switch,
    "rocker": paint_switch,
    "lever": paint_lever,
    "door": paint_door,
    "lid": paint_lid,
    "cover": paint_lid,
    "drawer": paint_drawer,
    "basket": paint_drawer,
    "tray": paint_drawer,
    "tank": paint_tank,
    "cap": paint_cap,
    "head": paint_head,
    "nozzle": paint_nozzle,
    "attachment": paint_attachment,
    "port": paint_port,
    "plug": paint_plug,
    "cable": paint_cable,
    "handle": paint_handle,
    "grip": paint_grip,
    "handset": paint_handset,
    "body": paint_body,
    "platform": paint_platform,
    "blade": paint_blade,
}


def paint_part(part: Part, size: tuple[int, int], pal: Palette) -> tuple[Image.Image, bool]:
    """An RGBA layer of exactly `size` with the part drawn on it, and whether its label was
    drawn on it (painters that print no label return None: it goes beside the part)."""
    w, h = size
    layer = Image.new("RGBA", (max(1, w), max(1, h)), (0, 0, 0, 0))
    d = ImageDraw.Draw(layer)
    painter = PAINTERS.get(part.spec.kind, paint_button)
    labelled = painter(d, w, h, part, pal)
    return layer, bool(labelled) or not part.spec.label
