"""Drawing an SSM of one of our categories that the layout does not reproduce (hand-written,
edited, or from an older generator): components are drawn at the SSM's own bboxes, the body
around them, so the picture still matches the annotations exactly."""

from __future__ import annotations

from PIL import Image, ImageDraw

from replay import AXONOMETRIC_VIEWS as AXO
from replay import DASHBOARD
from replay.semantics import BACK_BOTTOM, FRONT, ORTHOGRAPHIC_VIEWS

from ._catalog import ComponentSpec, load_catalog
from ._geometry import (
    Box3,
    Palette,
    Part,
    Style,
)
from ._lettering import centered_text
from ._paint import paint_part
from ._rng import derive_seed
from ._shapes import ACCENT_COLORS, darker, ink_on

_PALETTE = Palette((214, 216, 220), (150, 152, 158), (220, 60, 50), (40, 44, 52), (246, 246, 246))
_GUESS = (
    ("knob", "knob"),
    ("dial", "dial"),
    ("wheel", "wheel"),
    ("ring", "ring"),
    ("slider", "slider"),
    ("switch", "switch"),
    ("lever", "lever"),
    ("door", "door"),
    ("lid", "lid"),
    ("cover", "cover"),
    ("drawer", "drawer"),
    ("basket", "basket"),
    ("tank", "tank"),
    ("port", "port"),
    ("plug", "plug"),
    ("cord", "cable"),
    ("cable", "cable"),
    ("handle", "handle"),
    ("trigger", "trigger"),
    ("lens", "lens"),
    ("cap", "cap"),
)
SS = 2


def _spec_for(category: str, component: str) -> ComponentSpec:
    try:
        spec = load_catalog(category).components.get(component)
    except FileNotFoundError:
        spec = None
    if spec is not None:
        return spec
    kind = next((k for token, k in _GUESS if token in component), "button")
    return ComponentSpec(kind=kind, label="", faces=(FRONT,), required=True, size="small")


def _view_boxes(ssm, view: str) -> tuple[tuple[int, int] | None, dict[str, list[float]]]:
    size = None
    boxes: dict[str, list[float]] = {}
    for sdef in ssm.states.values():
        for comp, trans in sdef.on.items():
            for t in trans:
                for b in t.bbox:
                    if b.view.lower() != view:
                        continue
                    x, y, w, h, W, H = (float(v) for v in b.coordinate)
                    size = size or (round(W), round(H))
                    boxes.setdefault(comp, [x, y, x + w, y + h])
    return size, boxes


def _sibling_size(ssm) -> tuple[int, int]:
    for view in ORTHOGRAPHIC_VIEWS:
        size, _ = _view_boxes(ssm, view)
        if size:
            return size
    return (1000, 1000)


def render_foreign(ssm, category: str, view: str) -> Image.Image:
    """An RGB picture of `view` with each component at its bbox."""
    view = view.lower()
    size, boxes = _view_boxes(ssm, view)
    if size is None:
        size = _sibling_size(ssm)
    W, H = size
    canvas = Image.new("RGBA", (W * SS, H * SS), _PALETTE.background + (255,))
    d = ImageDraw.Draw(canvas)
    if view in AXO:
        _generic_box(d, W * SS, H * SS, view)
    elif view == DASHBOARD:
        d.rectangle((0, 0, W * SS, H * SS), fill=_PALETTE.panel)
    else:
        if boxes:
            x0 = min(b[0] for b in boxes.values())
            y0 = min(b[1] for b in boxes.values())
            x1 = max(b[2] for b in boxes.values())
            y1 = max(b[3] for b in boxes.values())
        else:
            x0, y0, x1, y1 = W * 0.3, H * 0.3, W * 0.7, H * 0.7
        body = (
            max(W * 0.04, min(x0 - W * 0.1, W * 0.2)),
            max(H * 0.04, min(y0 - H * 0.1, H * 0.2)),
            min(W * 0.96, max(x1 + W * 0.1, W * 0.8)),
            min(H * 0.96, max(y1 + H * 0.1, H * 0.8)),
        )
        body = tuple(v * SS for v in body)
        d.rounded_rectangle(
            body,
            radius=min(W, H) * 0.04 * SS,
            fill=_PALETTE.body,
            outline=darker(_PALETTE.body, 0.4),
            width=3 * SS,
        )
    for comp, (bx0, by0, bx1, by1) in sorted(boxes.items()):
        spec = _spec_for(category, comp)
        k = derive_seed("foreign", comp)  # the same look in every view
        style = Style(ACCENT_COLORS[k % len(ACCENT_COLORS)], k % 4)
        orientation = "h" if bx1 - bx0 >= by1 - by0 else "v"
        part = Part(comp, spec, (view,), Box3((0, 0, 0), (1, 1, 1)), style, orientation)
        px0, py0 = round(bx0) * SS, round(by0) * SS
        px1, py1 = round(bx1) * SS, round(by1) * SS
        if px1 - px0 < 2 or py1 - py0 < 2:
            continue
        layer, _ = paint_part(part, (px1 - px0, py1 - py0), _PALETTE)
        canvas.alpha_composite(layer, (px0, py0))
    return canvas.reduce(SS).convert("RGB")


def _generic_box(d: ImageDraw.ImageDraw, W: int, H: int, view: str) -> None:
    """An anonymous box in perspective (no layout to project)."""
    cx, cy = W / 2, H / 2
    s = min(W, H) * 0.3
    top = [(cx - s, cy - s * 0.6), (cx, cy - s), (cx + s, cy - s * 0.6), (cx, cy - s * 0.2)]
    left = [(cx - s, cy - s * 0.6), (cx, cy - s * 0.2), (cx, cy + s), (cx - s, cy + s * 0.6)]
    right = [(cx, cy - s * 0.2), (cx + s, cy - s * 0.6), (cx + s, cy + s * 0.6), (cx, cy + s)]
    body = _PALETTE.body
    if view == BACK_BOTTOM:
        top = [(x, H - y) for x, y in top]
        left = [(x, H - y) for x, y in left]
        right = [(x, H - y) for x, y in right]
    d.polygon(top, fill=body, outline=darker(body, 0.4))
    d.polygon(left, fill=darker(body, 0.12), outline=darker(body, 0.4))
    d.polygon(right, fill=darker(body, 0.25), outline=darker(body, 0.4))
    label_box = (0, H * 0.86, W, H * 0.98)
    centered_text(
        d, label_box, view.replace("_", " "), ink_on(_PALETTE.background), round(H * 0.05)
    )
