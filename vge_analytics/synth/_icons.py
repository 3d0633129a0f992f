"""Pictograms printed on controls (`icon:<name>` labels), drawn with plain vector shapes so
they look the same on every machine. Unknown names fall back to a short text badge."""

from __future__ import annotations

import math
from collections.abc import Callable

from PIL import ImageDraw

from ._strokes import radial_ticks

Color = tuple[int, int, int] | tuple[int, int, int, int]
Box = tuple[float, float, float, float]


def _wh(box: Box) -> tuple[float, float, float, float, float]:
    x0, y0, x1, y1 = box
    s = min(x1 - x0, y1 - y0)
    return (x0 + x1) / 2.0, (y0 + y1) / 2.0, s, x1 - x0, y1 - y0


def _lw(s: float) -> int:
    return max(1, round(s * 0.09))


def power(d: ImageDraw.ImageDraw, box: Box, ink: Color) -> None:
    cx, cy, s, _, _ = _wh(box)
    r = s * 0.34
    w = _lw(s)
    d.arc((cx - r, cy - r, cx + r, cy + r), start=-60, end=240, fill=ink, width=w)
    d.line((cx, cy - r * 1.25, cx, cy - r * 0.1), fill=ink, width=w)


def plug(d: ImageDraw.ImageDraw, box: Box, ink: Color) -> None:
    cx, cy, s, _, _ = _wh(box)
    w = _lw(s)
    d.rounded_rectangle(
        (cx - s * 0.22, cy - s * 0.1, cx + s * 0.22, cy + s * 0.2),
        radius=s * 0.06,
        outline=ink,
        width=w,
    )
    d.line((cx - s * 0.1, cy - s * 0.1, cx - s * 0.1, cy - s * 0.35), fill=ink, width=w)
    d.line((cx + s * 0.1, cy - s * 0.1, cx + s * 0.1, cy - s * 0.35), fill=ink, width=w)
    d.line((cx, cy + s * 0.2, cx, cy + s * 0.4), fill=ink, width=w)


def lock(d: ImageDraw.ImageDraw, box: Box, ink: Color, open_: bool = False) -> None:
    cx, cy, s, _, _ = _wh(box)
    w = _lw(s)
    d.rectangle((cx - s * 0.24, cy - s * 0.02, cx + s * 0.24, cy + s * 0.32), fill=ink)
    r = s * 0.16
    top = cy - s * 0.3
    if open_:
        d.arc(
            (cx - r + s * 0.12, top, cx + r + s * 0.12, top + 2 * r),
            start=180,
            end=360,
            fill=ink,
            width=w,
        )
        d.line((cx + s * 0.28, top + r, cx + s * 0.28, top + r * 1.3), fill=ink, width=w)
        d.line((cx - r + s * 0.12, top + r, cx - r + s * 0.12, cy), fill=ink, width=w)
    else:
        d.arc((cx - r, top, cx + r, top + 2 * r), start=180, end=360, fill=ink, width=w)
        d.line((cx - r, top + r, cx - r, cy), fill=ink, width=w)
        d.line((cx + r, top + r, cx + r, cy), fill=ink, width=w)


def sun(d: ImageDraw.ImageDraw, box: Box, ink: Color) -> None:
    cx, cy, s, _, _ = _wh(box)
    w = _lw(s)
    r = s * 0.16
    d.ellipse((cx - r, cy - r, cx + r, cy + r), outline=ink, width=w)
    radial_ticks(d, cx, cy, r, 1.5, 2.3, (k * math.pi / 4 for k in range(8)), fill=ink, width=w)


def light(d: ImageDraw.ImageDraw, box: Box, ink: Color) -> None:
    cx, cy, s, _, _ = _wh(box)
    w = _lw(s)
    r = s * 0.2
    d.ellipse((cx - r, cy - r * 1.4, cx + r, cy + r * 0.6), outline=ink, width=w)
    d.rectangle((cx - r * 0.5, cy + r * 0.7, cx + r * 0.5, cy + r * 1.3), fill=ink)
    for a in (-150, -90, -30):
        t = math.radians(a)
        d.line(
            (
                cx + math.cos(t) * r * 1.5,
                cy - r * 0.4 + math.sin(t) * r * 1.5,
                cx + math.cos(t) * r * 2.1,
                cy - r * 0.4 + math.sin(t) * r * 2.1,
            ),
            fill=ink,
            width=w,
        )


def moon(d: ImageDraw.ImageDraw, box: Box, ink: Color, bg: Color) -> None:
    cx, cy, s, _, _ = _wh(box)
    r = s * 0.3
    d.ellipse((cx - r, cy - r, cx + r, cy + r), fill=ink)
    d.ellipse((cx - r * 0.35, cy - r * 1.05, cx + r * 1.4, cy + r * 0.7), fill=bg)


def fan(d: ImageDraw.ImageDraw, box: Box, ink: Color) -> None:
    cx, cy, s, _, _ = _wh(box)
    r = s * 0.36
    for k in range(3):
        a = k * 120
        d.pieslice((cx - r, cy - r, cx + r, cy + r), start=a, end=a + 50, fill=ink)
    d.ellipse((cx - s * 0.07, cy - s * 0.07, cx + s * 0.07, cy + s * 0.07), fill=ink)


def snowflake(d: ImageDraw.ImageDraw, box: Box, ink: Color) -> None:
    cx, cy, s, _, _ = _wh(box)
    w = _lw(s)
    r = s * 0.36
    for k in range(3):
        a = math.radians(90 + k * 60)
        d.line(
            (
                cx - math.cos(a) * r,
                cy - math.sin(a) * r,
                cx + math.cos(a) * r,
                cy + math.sin(a) * r,
            ),
            fill=ink,
            width=w,
        )


def play(d: ImageDraw.ImageDraw, box: Box, ink: Color) -> None:
    cx, cy, s, _, _ = _wh(box)
    d.polygon(
        [(cx - s * 0.2, cy - s * 0.28), (cx - s * 0.2, cy + s * 0.28), (cx + s * 0.28, cy)],
        fill=ink,
    )


def flash(d: ImageDraw.ImageDraw, box: Box, ink: Color) -> None:
    cx, cy, s, _, _ = _wh(box)
    pts = [
        (cx + s * 0.08, cy - s * 0.38),
        (cx - s * 0.2, cy + s * 0.04),
        (cx - s * 0.02, cy + s * 0.04),
        (cx - s * 0.1, cy + s * 0.38),
        (cx + s * 0.2, cy - s * 0.06),
        (cx + s * 0.02, cy - s * 0.06),
    ]
    d.polygon(pts, fill=ink)


def battery(d: ImageDraw.ImageDraw, box: Box, ink: Color) -> None:
    cx, cy, s, _, _ = _wh(box)
    w = _lw(s)
    d.rectangle((cx - s * 0.32, cy - s * 0.16, cx + s * 0.26, cy + s * 0.16), outline=ink, width=w)
    d.rectangle((cx + s * 0.26, cy - s * 0.07, cx + s * 0.34, cy + s * 0.07), fill=ink)
    d.rectangle((cx - s * 0.26, cy - s * 0.1, cx + s * 0.05, cy + s * 0.1), fill=ink)


def usb(d: ImageDraw.ImageDraw, box: Box, ink: Color) -> None:
    cx, cy, s, _, _ = _wh(box)
    w = _lw(s)
    d.line((cx - s * 0.34, cy, cx + s * 0.3, cy), fill=ink, width=w)
    d.polygon(
        [(cx + s * 0.38, cy), (cx + s * 0.26, cy - s * 0.08), (cx + s * 0.26, cy + s * 0.08)],
        fill=ink,
    )
    d.line((cx - s * 0.1, cy, cx, cy - s * 0.18, cx + s * 0.12, cy - s * 0.18), fill=ink, width=w)
    d.line(
        (cx - s * 0.02, cy, cx + s * 0.06, cy + s * 0.16, cx + s * 0.16, cy + s * 0.16),
        fill=ink,
        width=w,
    )
    d.ellipse((cx - s * 0.4, cy - s * 0.06, cx - s * 0.28, cy + s * 0.06), fill=ink)


def heat(d: ImageDraw.ImageDraw, box: Box, ink: Color) -> None:
    cx, cy, s, _, _ = _wh(box)
    w = _lw(s)
    for dx in (-0.18, 0.0, 0.18):
        pts = []
        for k in range(9):
            t = k / 8.0
            pts.append(
                (cx + s * dx + math.sin(t * 2 * math.pi) * s * 0.06, cy + s * (0.32 - 0.64 * t))
            )
        d.line(pts, fill=ink, width=w)


def thermometer(d: ImageDraw.ImageDraw, box: Box, ink: Color) -> None:
    cx, cy, s, _, _ = _wh(box)
    w = _lw(s)
    d.rounded_rectangle(
        (cx - s * 0.07, cy - s * 0.36, cx + s * 0.07, cy + s * 0.12),
        radius=s * 0.07,
        outline=ink,
        width=w,
    )
    d.ellipse((cx - s * 0.14, cy + s * 0.06, cx + s * 0.14, cy + s * 0.34), fill=ink)


def speaker(d: ImageDraw.ImageDraw, box: Box, ink: Color) -> None:
    cx, cy, s, _, _ = _wh(box)
    w = _lw(s)
    d.polygon(
        [
            (cx - s * 0.3, cy - s * 0.1),
            (cx - s * 0.16, cy - s * 0.1),
            (cx, cy - s * 0.26),
            (cx, cy + s * 0.26),
            (cx - s * 0.16, cy + s * 0.1),
            (cx - s * 0.3, cy + s * 0.1),
        ],
        fill=ink,
    )
    for r in (0.14, 0.26):
        d.arc(
            (cx - s * r, cy - s * r, cx + s * r, cy + s * r), start=-45, end=45, fill=ink, width=w
        )


def arrows(d: ImageDraw.ImageDraw, box: Box, ink: Color) -> None:
    """Oscillation: a double-headed curved arrow."""
    cx, cy, s, _, _ = _wh(box)
    w = _lw(s)
    r = s * 0.3
    d.arc((cx - r, cy - r, cx + r, cy + r), start=200, end=340, fill=ink, width=w)
    for a in (200, 340):
        t = math.radians(a)
        px, py = cx + math.cos(t) * r, cy + math.sin(t) * r
        d.polygon([(px - s * 0.08, py), (px + s * 0.08, py), (px, py + s * 0.12)], fill=ink)


def clock(d: ImageDraw.ImageDraw, box: Box, ink: Color) -> None:
    cx, cy, s, _, _ = _wh(box)
    w = _lw(s)
    r = s * 0.32
    d.ellipse((cx - r, cy - r, cx + r, cy + r), outline=ink, width=w)
    d.line((cx, cy, cx, cy - r * 0.7), fill=ink, width=w)
    d.line((cx, cy, cx + r * 0.5, cy), fill=ink, width=w)


def bell(d: ImageDraw.ImageDraw, box: Box, ink: Color) -> None:
    cx, cy, s, _, _ = _wh(box)
    d.pieslice(
        (cx - s * 0.26, cy - s * 0.3, cx + s * 0.26, cy + s * 0.22), start=180, end=360, fill=ink
    )
    d.rectangle((cx - s * 0.26, cy - s * 0.04, cx + s * 0.26, cy + s * 0.14), fill=ink)
    d.ellipse((cx - s * 0.06, cy + s * 0.16, cx + s * 0.06, cy + s * 0.28), fill=ink)


def lid_open(d: ImageDraw.ImageDraw, box: Box, ink: Color) -> None:
    cx, cy, s, _, _ = _wh(box)
    w = _lw(s)
    d.rectangle((cx - s * 0.28, cy, cx + s * 0.28, cy + s * 0.3), outline=ink, width=w)
    d.line((cx - s * 0.28, cy - s * 0.04, cx + s * 0.16, cy - s * 0.34), fill=ink, width=w)


def car(d: ImageDraw.ImageDraw, box: Box, ink: Color) -> None:
    cx, cy, s, _, _ = _wh(box)
    d.rounded_rectangle(
        (cx - s * 0.36, cy - s * 0.04, cx + s * 0.36, cy + s * 0.18), radius=s * 0.05, fill=ink
    )
    d.polygon(
        [
            (cx - s * 0.22, cy - s * 0.04),
            (cx - s * 0.12, cy - s * 0.22),
            (cx + s * 0.14, cy - s * 0.22),
            (cx + s * 0.24, cy - s * 0.04),
        ],
        fill=ink,
    )
    for dx in (-0.2, 0.2):
        d.ellipse(
            (cx + s * dx - s * 0.07, cy + s * 0.12, cx + s * dx + s * 0.07, cy + s * 0.26), fill=ink
        )


def book(d: ImageDraw.ImageDraw, box: Box, ink: Color) -> None:
    cx, cy, s, _, _ = _wh(box)
    w = _lw(s)
    d.polygon(
        [
            (cx, cy - s * 0.2),
            (cx - s * 0.32, cy - s * 0.28),
            (cx - s * 0.32, cy + s * 0.22),
            (cx, cy + s * 0.3),
        ],
        outline=ink,
        width=w,
    )
    d.polygon(
        [
            (cx, cy - s * 0.2),
            (cx + s * 0.32, cy - s * 0.28),
            (cx + s * 0.32, cy + s * 0.22),
            (cx, cy + s * 0.3),
        ],
        outline=ink,
        width=w,
    )


def person(d: ImageDraw.ImageDraw, box: Box, ink: Color) -> None:
    cx, cy, s, _, _ = _wh(box)
    d.ellipse((cx - s * 0.1, cy - s * 0.36, cx + s * 0.1, cy - s * 0.16), fill=ink)
    d.rounded_rectangle(
        (cx - s * 0.2, cy - s * 0.12, cx + s * 0.2, cy + s * 0.34), radius=s * 0.1, fill=ink
    )


def bin_open(d: ImageDraw.ImageDraw, box: Box, ink: Color) -> None:
    cx, cy, s, _, _ = _wh(box)
    w = _lw(s)
    d.polygon(
        [
            (cx - s * 0.22, cy - s * 0.1),
            (cx + s * 0.22, cy - s * 0.1),
            (cx + s * 0.16, cy + s * 0.34),
            (cx - s * 0.16, cy + s * 0.34),
        ],
        outline=ink,
        width=w,
    )
    d.line((cx - s * 0.28, cy - s * 0.18, cx + s * 0.12, cy - s * 0.36), fill=ink, width=w)


def trimmer(d: ImageDraw.ImageDraw, box: Box, ink: Color) -> None:
    cx, cy, s, _, _ = _wh(box)
    d.rectangle((cx - s * 0.12, cy - s * 0.1, cx + s * 0.12, cy + s * 0.34), fill=ink)
    for k in range(5):
        x = cx - s * 0.12 + k * s * 0.06
        d.line((x, cy - s * 0.1, x, cy - s * 0.3), fill=ink, width=max(1, round(s * 0.03)))


def torch(d: ImageDraw.ImageDraw, box: Box, ink: Color) -> None:
    cx, cy, s, _, _ = _wh(box)
    d.polygon(
        [
            (cx - s * 0.34, cy - s * 0.08),
            (cx, cy - s * 0.08),
            (cx + s * 0.12, cy - s * 0.18),
            (cx + s * 0.12, cy + s * 0.18),
            (cx, cy + s * 0.08),
            (cx - s * 0.34, cy + s * 0.08),
        ],
        fill=ink,
    )
    for a in (-20, 0, 20):
        t = math.radians(a)
        d.line(
            (cx + s * 0.18, cy + math.sin(t) * s * 0.1, cx + s * 0.38, cy + math.sin(t) * s * 0.3),
            fill=ink,
            width=_lw(s),
        )


def remote(d: ImageDraw.ImageDraw, box: Box, ink: Color) -> None:
    cx, cy, s, _, _ = _wh(box)
    w = _lw(s)
    for r in (0.12, 0.24, 0.36):
        d.arc(
            (cx - s * r, cy - s * r, cx + s * r, cy + s * r), start=225, end=315, fill=ink, width=w
        )
    d.ellipse((cx - s * 0.05, cy - s * 0.05, cx + s * 0.05, cy + s * 0.05), fill=ink)


ICONS: dict[str, Callable] = {
    "power": power,
    "plug": plug,
    "lock": lock,
    "child_lock": lock,
    "unlock": lambda d, b, ink: lock(d, b, ink, open_=True),
    "light": light,
    "sun": sun,
    "fan": fan,
    "snowflake": snowflake,
    "play": play,
    "flash": flash,
    "battery": battery,
    "usb": usb,
    "heat": heat,
    "thermometer": thermometer,
    "speaker": speaker,
    "oscillate": arrows,
    "time_wind": clock,
    "bell_wind": bell,
    "lid_open": lid_open,
    "head_open": lid_open,
    "bin_open": bin_open,
    "trunk": car,
    "remote_start": remote,
    "book": book,
    "body_fat": person,
    "trimmer": trimmer,
    "torch": torch,
}


def draw_icon(
    d: ImageDraw.ImageDraw, name: str, box: Box, ink: Color, bg: Color, text_fallback: Callable
) -> None:
    """Draw `icon:<name>` inside `box`; unknown names become a text badge."""
    if name == "moon":
        moon(d, box, ink, bg)
        return
    fn = ICONS.get(name)
    if fn is not None:
        fn(d, box, ink)
        return
    text_fallback(name.replace("_", " ").upper()[:6])
