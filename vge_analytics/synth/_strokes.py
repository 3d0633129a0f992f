"""Vector strokes that painters, icons and motifs share."""

from __future__ import annotations

import math
from collections.abc import Iterable

from PIL import ImageDraw


def radial_ticks(
    d: ImageDraw.ImageDraw,
    cx: float,
    cy: float,
    r: float,
    inner: float,
    outer: float,
    angles: Iterable[float],
    *,
    fill: tuple[int, ...],
    width: int,
) -> None:
    """One line per angle (radians) from `inner * r` to `outer * r` around (cx, cy): the ticks
    of a dial, the ridges of a grip, the rays of a sun."""
    for a in angles:
        cos, sin = math.cos(a), math.sin(a)
        d.line(
            (
                cx + cos * r * inner,
                cy + sin * r * inner,
                cx + cos * r * outer,
                cy + sin * r * outer,
            ),
            fill=fill,
            width=width,
        )
