"""Non-interactive details that make a device recognisable at a glance: a coffee machine's cup
bay, a fan's grille, a clock face, a camera's lens, a display... Each motif sits on one view
at a preferred place and is drawn only where it covers no component (and no other motif)."""

from __future__ import annotations

import math
from collections.abc import Callable

from PIL import ImageDraw

from replay.semantics import BACK, FRONT, LEFT, RIGHT, TOP

from ._shapes import darker, lighter
from ._strokes import radial_ticks

Rect = tuple[float, float, float, float]
# (view, (x0, y0, x1, y1) as fractions of the body's rectangle in that view, painter)
Motif = tuple[str, Rect, str]


def _lcd(d: ImageDraw.ImageDraw, r: Rect, body, text_fn) -> None:
    d.rounded_rectangle(
        r, radius=(r[3] - r[1]) * 0.12, fill=(24, 44, 34), outline=(12, 20, 16), width=3
    )
    text_fn(d, r, "12:30", (120, 235, 160))


def _screen(d, r: Rect, body, text_fn) -> None:
    d.rounded_rectangle(
        r, radius=(r[3] - r[1]) * 0.06, fill=(26, 30, 38), outline=(10, 10, 12), width=3
    )
    w, h = r[2] - r[0], r[3] - r[1]
    d.polygon(
        [
            (r[0] + w * 0.05, r[1] + h * 0.05),
            (r[0] + w * 0.3, r[1] + h * 0.05),
            (r[0] + w * 0.05, r[1] + h * 0.5),
        ],
        fill=(60, 66, 80),
    )


def _grille_round(d, r: Rect, body, text_fn) -> None:
    cx, cy = (r[0] + r[2]) / 2, (r[1] + r[3]) / 2
    rad = min(r[2] - r[0], r[3] - r[1]) / 2
    dark = darker(body, 0.45)
    d.ellipse(
        (cx - rad, cy - rad, cx + rad, cy + rad), fill=lighter(body, 0.1), outline=dark, width=4
    )
    for k in range(1, 5):
        rr = rad * k / 5
        d.ellipse((cx - rr, cy - rr, cx + rr, cy + rr), outline=dark, width=2)
    for k in range(12):
        a = math.radians(k * 30)
        d.line((cx, cy, cx + math.cos(a) * rad, cy + math.sin(a) * rad), fill=dark, width=2)
    d.ellipse((cx - rad * 0.15, cy - rad * 0.15, cx + rad * 0.15, cy + rad * 0.15), fill=dark)


def _slots(d, r: Rect, body, text_fn) -> None:
    dark = darker(body, 0.35)
    h = r[3] - r[1]
    n = max(3, int(h / 24))
    for k in range(n):
        y = r[1] + h * (k + 0.25) / n
        d.rounded_rectangle((r[0], y, r[2], y + h * 0.45 / n), radius=h * 0.2 / n, fill=dark)


def _dots(d, r: Rect, body, text_fn) -> None:
    dark = darker(body, 0.3)
    w, h = r[2] - r[0], r[3] - r[1]
    step = max(10.0, min(w, h) / 9)
    y = r[1] + step / 2
    while y < r[3]:
        x = r[0] + step / 2
        while x < r[2]:
            d.ellipse((x - step * 0.2, y - step * 0.2, x + step * 0.2, y + step * 0.2), fill=dark)
            x += step
        y += step


def _clock_face(d, r: Rect, body, text_fn) -> None:
    cx, cy = (r[0] + r[2]) / 2, (r[1] + r[3]) / 2
    rad = min(r[2] - r[0], r[3] - r[1]) / 2
    d.ellipse(
        (cx - rad, cy - rad, cx + rad, cy + rad),
        fill=(248, 246, 238),
        outline=(40, 40, 40),
        width=5,
    )
    hours = (math.radians(k * 30) for k in range(12))
    radial_ticks(d, cx, cy, rad, 0.8, 0.92, hours, fill=(40, 40, 40), width=4)
    d.line((cx, cy, cx + rad * 0.45, cy - rad * 0.2), fill=(30, 30, 30), width=7)
    d.line((cx, cy, cx - rad * 0.1, cy - rad * 0.7), fill=(30, 30, 30), width=5)
    d.line((cx, cy, cx + rad * 0.3, cy + rad * 0.55), fill=(200, 40, 40), width=3)


def _lens(d, r: Rect, body, text_fn) -> None:
    cx, cy = (r[0] + r[2]) / 2, (r[1] + r[3]) / 2
    rad = min(r[2] - r[0], r[3] - r[1]) / 2
    for frac, col in (
        (1.0, (40, 40, 44)),
        (0.82, (90, 92, 98)),
        (0.66, (18, 22, 34)),
        (0.4, (34, 50, 90)),
    ):
        rr = rad * frac
        d.ellipse((cx - rr, cy - rr, cx + rr, cy + rr), fill=col)
    d.ellipse(
        (cx - rad * 0.35, cy - rad * 0.4, cx - rad * 0.1, cy - rad * 0.15), fill=(200, 210, 240)
    )


def _cup_bay(d, r: Rect, body, text_fn) -> None:
    w, h = r[2] - r[0], r[3] - r[1]
    d.rounded_rectangle(r, radius=min(w, h) * 0.08, fill=(40, 40, 44))
    d.rectangle((r[0] + w * 0.4, r[1], r[0] + w * 0.6, r[1] + h * 0.14), fill=(120, 120, 126))
    d.rounded_rectangle(
        (r[0] + w * 0.3, r[1] + h * 0.5, r[0] + w * 0.7, r[3] - h * 0.08),
        radius=w * 0.05,
        fill=(240, 240, 236),
    )
    d.rectangle(
        (r[0] + w * 0.05, r[3] - h * 0.08, r[2] - w * 0.05, r[3] - h * 0.02), fill=(150, 150, 156)
    )


def _porthole(d, r: Rect, body, text_fn) -> None:
    cx, cy = (r[0] + r[2]) / 2, (r[1] + r[3]) / 2
    rad = min(r[2] - r[0], r[3] - r[1]) / 2
    d.ellipse(
        (cx - rad, cy - rad, cx + rad, cy + rad),
        fill=(200, 202, 208),
        outline=(120, 122, 128),
        width=6,
    )
    d.ellipse(
        (cx - rad * 0.72, cy - rad * 0.72, cx + rad * 0.72, cy + rad * 0.72), fill=(60, 80, 110)
    )


def _keypad(d, r: Rect, body, text_fn) -> None:
    w, h = r[2] - r[0], r[3] - r[1]
    keys = "123456789*0#"
    for k, ch in enumerate(keys):
        i, j = k % 3, k // 3
        x0 = r[0] + w * i / 3 + w * 0.04
        y0 = r[1] + h * j / 4 + h * 0.03
        box = (x0, y0, x0 + w / 3 - w * 0.08, y0 + h / 4 - h * 0.06)
        d.rounded_rectangle(box, radius=4, fill=(236, 236, 232), outline=(120, 120, 120))
        text_fn(d, box, ch, (30, 30, 30))


def _head(d, r: Rect, body, text_fn) -> None:
    """A nozzle, bezel or blade head on the end of the device."""
    w, h = r[2] - r[0], r[3] - r[1]
    d.rounded_rectangle(r, radius=min(w, h) * 0.25, fill=(70, 72, 78))
    d.rounded_rectangle(
        (r[0] + w * 0.1, r[1] + h * 0.15, r[2] - w * 0.1, r[3] - h * 0.15),
        radius=min(w, h) * 0.2,
        fill=(190, 194, 200),
    )


def _ring_hole(d, r: Rect, body, text_fn) -> None:
    cx, cy = (r[0] + r[2]) / 2, (r[1] + r[3]) / 2
    rad = min(r[2] - r[0], r[3] - r[1]) / 2
    d.ellipse((cx - rad, cy - rad, cx + rad, cy + rad), fill=darker(body, 0.2))
    d.ellipse(
        (cx - rad * 0.55, cy - rad * 0.55, cx + rad * 0.55, cy + rad * 0.55), fill=(250, 250, 250)
    )


def _leds(d, r: Rect, body, text_fn) -> None:
    w = r[2] - r[0]
    cy = (r[1] + r[3]) / 2
    rad = min(w / 10, (r[3] - r[1]) / 2)
    for k in range(4):
        cx = r[0] + w * (k + 0.5) / 4
        d.ellipse(
            (cx - rad, cy - rad, cx + rad, cy + rad), fill=(80, 200, 120) if k < 3 else (60, 64, 70)
        )


PAINTERS: dict[str, Callable] = {
    "lcd": _lcd,
    "screen": _screen,
    "grille_round": _grille_round,
    "slots": _slots,
    "dots": _dots,
    "clock_face": _clock_face,
    "lens": _lens,
    "cup_bay": _cup_bay,
    "porthole": _porthole,
    "keypad": _keypad,
    "head": _head,
    "ring_hole": _ring_hole,
    "leds": _leds,
}

MOTIFS: dict[str, tuple[Motif, ...]] = {
    "AirFryer": ((FRONT, (0.2, 0.12, 0.8, 0.3), "lcd"), (TOP, (0.2, 0.2, 0.8, 0.8), "slots")),
    "AirPurifier": (
        (FRONT, (0.15, 0.35, 0.85, 0.9), "dots"),
        (TOP, (0.15, 0.15, 0.85, 0.85), "slots"),
    ),
    "CarKey": ((FRONT, (0.35, 0.03, 0.65, 0.16), "ring_hole"),),
    "CoffeeMachine": (
        (FRONT, (0.25, 0.45, 0.75, 0.92), "cup_bay"),
        (FRONT, (0.3, 0.1, 0.7, 0.28), "lcd"),
    ),
    "DigitalAlarmClock": (
        (FRONT, (0.12, 0.15, 0.88, 0.7), "lcd"),
        (BACK, (0.2, 0.2, 0.8, 0.6), "dots"),
    ),
    "DigitalCamera": (
        (FRONT, (0.3, 0.2, 0.7, 0.8), "lens"),
        (BACK, (0.1, 0.15, 0.65, 0.85), "screen"),
    ),
    "ElectricFan": (
        (FRONT, (0.1, 0.05, 0.9, 0.6), "grille_round"),
        (BACK, (0.1, 0.05, 0.9, 0.6), "grille_round"),
    ),
    "ElectricKettle": ((TOP, (0.25, 0.25, 0.75, 0.75), "slots"),),
    "ElectricToothbrush": (
        (TOP, (0.2, 0.2, 0.8, 0.8), "head"),
        (FRONT, (0.3, 0.02, 0.7, 0.22), "head"),
    ),
    "FilmCamera": (
        (FRONT, (0.3, 0.2, 0.7, 0.85), "lens"),
        (BACK, (0.12, 0.1, 0.35, 0.3), "screen"),
    ),
    "Flashlight": ((TOP, (0.1, 0.1, 0.9, 0.9), "lens"),),
    "HairDryer": (
        (LEFT, (0.1, 0.05, 0.9, 0.4), "grille_round"),
        (RIGHT, (0.1, 0.05, 0.9, 0.4), "grille_round"),
    ),
    "Heater": ((FRONT, (0.1, 0.3, 0.9, 0.9), "slots"),),
    "Humidifier": (
        (TOP, (0.3, 0.3, 0.7, 0.7), "grille_round"),
        (FRONT, (0.2, 0.1, 0.8, 0.35), "leds"),
    ),
    "Lamp": ((TOP, (0.15, 0.15, 0.85, 0.85), "grille_round"),),
    "Landline": ((TOP, (0.35, 0.3, 0.9, 0.95), "keypad"), (TOP, (0.05, 0.08, 0.3, 0.3), "lcd")),
    "Lighter": ((TOP, (0.25, 0.2, 0.75, 0.8), "dots"),),
    "MechanicalAlarmClock": ((FRONT, (0.08, 0.15, 0.92, 0.85), "clock_face"),),
    "Microwave": ((FRONT, (0.7, 0.08, 0.95, 0.22), "lcd"),),
    "PowerBank": ((FRONT, (0.25, 0.75, 0.75, 0.82), "leds"),),
    "Razor": ((TOP, (0.1, 0.1, 0.9, 0.9), "head"), (FRONT, (0.15, 0.02, 0.85, 0.2), "head")),
    "RiceCooker": (
        (FRONT, (0.3, 0.45, 0.7, 0.62), "lcd"),
        (TOP, (0.35, 0.35, 0.65, 0.65), "slots"),
    ),
    "ThermometerGun": (
        (BACK, (0.15, 0.1, 0.85, 0.35), "lcd"),
        (FRONT, (0.2, 0.08, 0.8, 0.3), "lens"),
    ),
    "Vacuum": ((FRONT, (0.25, 0.35, 0.75, 0.6), "dots"),),
    "WashingMachine": (
        (FRONT, (0.15, 0.3, 0.85, 0.9), "porthole"),
        (FRONT, (0.55, 0.05, 0.9, 0.16), "lcd"),
    ),
    "WeighingScale": ((TOP, (0.3, 0.08, 0.7, 0.24), "lcd"),),
}
