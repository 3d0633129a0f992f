"""Where a view's picture comes from (PROTOCOL §1.1): one resolver for every picture a tool
shows of a step, so an MCAP frame, the dashboard and the environment show the same one.

The order is `BENCH/images/<device_id>/<view>.png|.jpg|.jpeg`, then the SSM's `images`
entry for the view, then the caller's fallback (the analytics render the views of the
synthetic categories). A file that is too large, or that is not a picture, counts as absent.
"""

from __future__ import annotations

import io
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

from ..semantics import Machine
from ._fs import Location, confined, location
from ._layout import image_paths, not_a_file_name, relative_inside

MAX_IMAGE_BYTES = 64 << 20
"""A view image file larger than this is not read (it counts as absent)."""

_FORMATS = {"PNG": "png", "JPEG": "jpeg", "WEBP": "webp"}
"""Pillow's format names -> the names `foxglove.CompressedImage` uses."""


class ViewImage(NamedTuple):
    """One view of a device as an encoded picture."""

    data: bytes
    format: str
    """`png`, `jpeg` or `webp`."""
    width: int
    height: int


ImageSource = Callable[[Machine, str], object]
"""`image_source(machine, view)`: the view's picture as a `ViewImage` (or a tuple or object
of the same four fields, read by `as_view_image`), or None. Must be picklable (a
module-level function, a `functools.partial` of one, or an instance like `BenchImages`)
when `replay_runs` uses worker processes."""


def as_view_image(got: object) -> ViewImage | None:
    """An image source's answer as a `ViewImage`: one already, a 4-tuple, or an object with
    `data`, `format`, `width` and `height`."""
    if got is None or isinstance(got, ViewImage):
        return got
    if isinstance(got, tuple):
        data, fmt, width, height = got[:4]
    else:
        data, fmt, width, height = got.data, got.format, got.width, got.height  # type: ignore[attr-defined]
    return ViewImage(bytes(data), str(fmt), int(width), int(height))


def decode_view_image(data: bytes) -> ViewImage | None:
    """Bytes as a `ViewImage` (format and size from the file's header), or None when they are
    not a PNG, JPEG or WebP picture."""
    from PIL import Image, UnidentifiedImageError  # imported on first use: only pictures need it

    try:
        with Image.open(io.BytesIO(data)) as img:
            fmt = _FORMATS.get(img.format or "")
            width, height = img.size
    except (OSError, ValueError, UnidentifiedImageError, Image.DecompressionBombError):
        return None
    return None if fmt is None else ViewImage(data, fmt, width, height)


def _read(path: Location) -> ViewImage | None:
    try:
        if not path.is_file():
            return None
        with path.open_read() as fh:
            data = fh.read(MAX_IMAGE_BYTES + 1)
    except OSError:
        return None
    return None if len(data) > MAX_IMAGE_BYTES else decode_view_image(data)


def bench_image(bench: str | Location, machine: Machine, view: str) -> ViewImage | None:
    """The benchmark's own picture of `view` (PROTOCOL §1.1 order), or None. Only a file
    inside BENCH is read: a view that cannot name a file, an `images` path that leaves BENCH
    (absolute, `..`, a link out) counts as absent."""
    view = view.lower()
    root = location(bench)
    if not_a_file_name(view) is None:
        for path in image_paths(root, machine.device_id, view):
            found = _read(path) if confined(root, path) else None
            if found is not None:
                return found
    ref = machine.images.get(view)
    if ref is None or not relative_inside(ref[0]) or not confined(root, root / ref[0]):
        return None
    return _read(root / ref[0])


@dataclass(frozen=True)
class BenchImages:
    """An image source (picklable): the benchmark's pictures (`bench_image`), else what
    `fallback(machine, view)` gives, if anything."""

    root: str
    fallback: ImageSource | None = None

    def __call__(self, machine: Machine, view: str) -> ViewImage | None:
        found = bench_image(self.root, machine, view)
        if found is None and self.fallback is not None:
            found = as_view_image(self.fallback(machine, view))
        return found


__all__ = [
    "MAX_IMAGE_BYTES",
    "BenchImages",
    "ImageSource",
    "ViewImage",
    "as_view_image",
    "bench_image",
    "decode_view_image",
]
