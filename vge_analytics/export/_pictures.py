"""The pictures of a device's views as an export embeds them: downscaled JPEG.

The pictures come from the one image resolver of the analytics, `vge_analytics.synth.
image_source(bench)` (the benchmark's own images, else the synthetic renderings). A view is
shown at every step spent in it, and in every run of the benchmark, so each picture is
decoded, scaled and encoded once and kept, up to `CACHED_BYTES` of them (the least recently
shown go first; episodes are exported in id order, which keeps a device's episodes
together). A picture of more pixels than a view picture may have (`replay.MAX_IMAGE_PIXELS`)
is never decoded: the step goes without it. The device's list of views (what the agent is
told it can switch to) comes from its compiled SSM, from the benchmark's own cache of
machines (`replay.Benchmark.machine`: a full-scale benchmark's 968 devices hold about 46 MB).
"""

from __future__ import annotations

import base64
import hashlib
import io
from collections import OrderedDict
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import replay

MAX_SIDE = 512
"""Longest side of an embedded picture, in pixels: the views stay readable, the logs small."""
JPEG_QUALITY = 85
CACHED_BYTES = 32 * 1024**2
"""Encoded pictures kept: the views of about 2,000 devices, a whole benchmark of the
bundled sample's size, so that its runs after the first reuse them."""


@dataclass(frozen=True)
class Picture:
    """A view's picture, ready to embed."""

    data: bytes
    media_type: str
    width: int
    height: int

    @property
    def name(self) -> str:
        """A file name for it, from its content (the same picture, the same name)."""
        return hashlib.sha256(self.data).hexdigest()[:20] + ".jpg"

    @cached_property
    def data_url(self) -> str:
        """The picture as a `data:` URL (made once: a view is shown at many steps)."""
        return f"data:{self.media_type};base64," + base64.b64encode(self.data).decode("ascii")


def shrink(data: bytes, name: str = "picture") -> Picture:
    """The picture scaled down to MAX_SIDE (never up), as JPEG. Raises `replay.PictureError`
    naming `name` for one with more pixels than a view picture may have (checked before
    decoding), or whose pixels do not decode."""
    rgb = replay.io.decode_picture(data, name)
    rgb.thumbnail((MAX_SIDE, MAX_SIDE))  # bicubic, reducing by 2 first when it can
    buf = io.BytesIO()
    rgb.save(buf, format="JPEG", quality=JPEG_QUALITY)
    return Picture(buf.getvalue(), "image/jpeg", rgb.width, rgb.height)


class Views:
    """The views of a benchmark's devices: their names, and their pictures on request."""

    def __init__(self, bench: Path | replay.Location) -> None:
        self.bench = replay.Benchmark.open(bench)
        self._where = bench
        self._source: replay.BenchImages | None = None  # made with the first picture asked
        self._names: dict[str, tuple[str, ...]] = {}
        self._pictures: OrderedDict[tuple[str, str], Picture | None] = OrderedDict()
        self._held = 0  # bytes of the pictures kept
        self._asked: dict[str, None] = {}  # the devices whose pictures were asked for
        self._undecoded: list[str] = []  # pictures that did not decode, one line each

    def names(self, device_id: str) -> tuple[str, ...]:
        """The views the device offers, in the SSM's order (kept for every device: small)."""
        got = self._names.get(device_id)
        if got is None:
            got = self._names[device_id] = tuple(self.bench.machine(device_id).views)
        return got

    def picture(self, device_id: str, view: str) -> Picture | None:
        """The view's picture, downscaled; None when the benchmark has none."""
        key = (device_id, view)
        if key in self._pictures:
            self._pictures.move_to_end(key)
            return self._pictures[key]
        if self._source is None:  # the renderer's modules: only an export with pictures
            from vge_analytics.synth import image_source

            self._source = image_source(self._where)
        self._asked.setdefault(device_id)
        found = self._source(self.bench.machine(device_id), view)
        name = f"device {device_id}, view {view}"
        try:
            got = shrink(found.data, name) if found is not None else None
        except replay.PictureError as exc:
            got = None  # not decoded: the step is exported without its picture
            self._undecoded.append(str(exc))
        self._pictures[key] = got
        self._held += len(got.data) if got is not None else 0
        while self._held > CACHED_BYTES:
            _, dropped = self._pictures.popitem(last=False)
            self._held -= len(dropped.data) if dropped is not None else 0
        return got

    def left_out(self) -> list[str]:
        """One line for each picture of the devices asked for that was there but is not
        shown: a benchmark file refused (too large, not a picture: PROTOCOL §1.1, as
        `vge validate` says it), or a picture whose pixels did not decode."""
        refused = replay.io.picture_problems(self.bench, self._asked) if self._asked else []
        return [str(p) for p in refused] + list(dict.fromkeys(self._undecoded))


__all__ = ["CACHED_BYTES", "JPEG_QUALITY", "MAX_SIDE", "Picture", "Views", "shrink"]
