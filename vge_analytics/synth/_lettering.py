"""Text on the rendered views: a font at a size, its extent, the largest size that fits a box,
and text centred in a box (labels of components and of views)."""

from __future__ import annotations

from PIL import ImageDraw, ImageFont


def font(size: int) -> ImageFont.FreeTypeFont | ImageFont.ImageFont:
    """PIL's built-in default font at a pixel size (the same on every machine)."""
    size = max(6, int(size))
    try:
        return ImageFont.load_default(size=size)
    except (TypeError, OSError):  # Pillow without FreeType: the fixed bitmap font
        return ImageFont.load_default()


def text_size(d: ImageDraw.ImageDraw, text: str, f) -> tuple[int, int]:
    x0, y0, x1, y1 = d.textbbox((0, 0), text, font=f)
    return x1 - x0, y1 - y0


def fit_font(d: ImageDraw.ImageDraw, text: str, max_w: float, max_h: float, start: int):
    """The largest font (down to 8 px) whose rendering of `text` fits max_w x max_h."""
    size = int(min(start, max_h))
    while size > 8:
        f = font(size)
        w, h = text_size(d, text, f)
        if w <= max_w and h <= max_h:
            return f
        size = int(size * 0.85)
    return None


MIN_TEXT = 24
"""Smallest label font on the (2x) drawing canvas: 12 px in the final image."""


def centered_text(
    d: ImageDraw.ImageDraw,
    box: tuple[float, float, float, float],
    text: str,
    ink,
    start: int,
    min_size: int = 8,
) -> bool:
    x0, y0, x1, y1 = box
    f = fit_font(d, text, (x1 - x0) * 0.9, (y1 - y0) * 0.8, start)
    if f is None or f.size < min_size:
        return False
    cx, cy = (x0 + x1) / 2.0, (y0 + y1) / 2.0
    d.text((cx, cy), text, font=f, fill=ink, anchor="mm")
    return True
