"""The current view as the environment shows it: a uint8 H x W x 3 array of a fixed size.

Views come from an image source (`replay.ImageSource`), the caller's: by default the
benchmark's own pictures (`replay.BenchImages`, PROTOCOL §1.1); the analytics package passes
one that also renders the views of the synthetic categories. Every view is resized to the
environment's size, which keeps the 0..1000 scale of the view exactly (the scale is relative
to width and height); a view without an image, or whose picture has more pixels than a view
picture may have (`replay.MAX_IMAGE_PIXELS`, checked before decoding), is a plain canvas
naming it.
"""

from __future__ import annotations

from collections import OrderedDict

import numpy as np
from PIL import Image, ImageDraw

from .._errors import PictureError
from ..io import ImageSource, as_view_image, decode_picture
from ..semantics import Machine

CANVAS = (236, 238, 242)
"""Colour of the stand-in for a view the benchmark has no image of."""


def no_images(machine: Machine, view: str) -> None:
    """An image source with no images: every view is the plain canvas (for agents that do
    not look, such as the simulated profiles, it saves rendering)."""
    return None


CACHE_BYTES = 32 << 20
"""Memory for the decoded, resized views of an environment: 682 views at 128 x 128 (the
bundled benchmark has 421), 18 at 768 x 768 (two devices)."""


class ViewImages:
    """Decoded, resized views, the least recently shown dropped past `cache_bytes`: decoding
    and resizing a picture costs about 20 ms, and RL code moves between devices at every
    reset (a cache of one device at a time decoded a view every fifth step)."""

    def __init__(
        self, source: ImageSource, width: int, height: int, cache_bytes: int = CACHE_BYTES
    ) -> None:
        self.source = source
        self.width = width
        self.height = height
        self.cache_bytes = cache_bytes
        self._cache: OrderedDict[tuple[str, str], np.ndarray] = OrderedDict()

    def array(self, machine: Machine, view: str) -> np.ndarray:
        """A fresh array of the view (callers own what they are given)."""
        key = (machine.device_id, view)
        got = self._cache.get(key)
        if got is None:
            got = self._cache[key] = self._load(machine, view)
            while len(self._cache) * got.nbytes > self.cache_bytes and len(self._cache) > 1:
                self._cache.popitem(last=False)
        else:
            self._cache.move_to_end(key)
        return got.copy()

    def _load(self, machine: Machine, view: str) -> np.ndarray:
        found = as_view_image(self.source(machine, view))
        size = (self.width, self.height)
        img = None if found is None else _decoded(found.data, view)
        if img is None:
            img = Image.new("RGB", size, CANVAS)
            ImageDraw.Draw(img).text((8, 8), f"no image of the {view} view", fill=(90, 90, 90))
        elif img.size != size:
            img = img.resize(size, Image.Resampling.BILINEAR)
        array = np.asarray(img, dtype=np.uint8)
        array.setflags(write=False)
        return array


def _decoded(data: bytes, view: str) -> Image.Image | None:
    """The picture as RGB, or None when it is not one, does not decode, or has more pixels
    than a view picture may have (`replay.io.decode_picture`: the header is checked first)."""
    try:
        return decode_picture(data, f"the {view} view")
    except PictureError:
        return None


__all__ = ["CACHE_BYTES", "ViewImages", "no_images"]
