"""The current view as the environment shows it: a uint8 H x W x 3 array of a fixed size.

Views come from an image source (`replay.ImageSource`), the caller's: by default the
benchmark's own pictures (`replay.BenchImages`, PROTOCOL §1.1); the analytics package passes
one that also renders the views of the synthetic categories. Every view is resized to the
environment's size, which keeps the 0..1000 scale of the view exactly (the scale is relative
to width and height); a view without an image is a plain canvas naming it.
"""

from __future__ import annotations

import io

import numpy as np
from PIL import Image, ImageDraw

from ..io._images import ImageSource, as_view_image
from ..semantics._machine import Machine

CANVAS = (236, 238, 242)
"""Colour of the stand-in for a view the benchmark has no image of."""


def no_images(machine: Machine, view: str) -> None:
    """An image source with no images: every view is the plain canvas (for agents that do
    not look, such as the simulated profiles, it saves rendering)."""
    return None


class ViewImages:
    """Decoded, resized views of one device at a time (the device of the current episode)."""

    def __init__(self, source: ImageSource, width: int, height: int) -> None:
        self.source = source
        self.width = width
        self.height = height
        self._device: str | None = None
        self._cache: dict[str, np.ndarray] = {}

    def array(self, machine: Machine, view: str) -> np.ndarray:
        """A fresh array of the view (callers own what they are given)."""
        if machine.device_id != self._device:
            self._device, self._cache = machine.device_id, {}
        got = self._cache.get(view)
        if got is None:
            got = self._cache[view] = self._load(machine, view)
        return got.copy()

    def _load(self, machine: Machine, view: str) -> np.ndarray:
        found = as_view_image(self.source(machine, view))
        size = (self.width, self.height)
        if found is None:
            img = Image.new("RGB", size, CANVAS)
            ImageDraw.Draw(img).text((8, 8), f"no image of the {view} view", fill=(90, 90, 90))
        else:
            with Image.open(io.BytesIO(found.data)) as raw:
                img = raw.convert("RGB")
            if img.size != size:
                img = img.resize(size, Image.Resampling.BILINEAR)
        array = np.asarray(img, dtype=np.uint8)
        array.setflags(write=False)
        return array


__all__ = ["ViewImages", "no_images"]
