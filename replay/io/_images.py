"""Where a view's picture comes from (PROTOCOL §1.1): one resolver for every picture a tool
shows of a step, so an MCAP frame, the dashboard and the environment show the same one.

The order is `BENCH/images/<device_id>/<view>.png|.jpg|.jpeg`, then the SSM's `images`
entry for the view, then the caller's fallback (the analytics render the views of the
synthetic categories). A file that is too large, in bytes or in pixels, or that is not a
picture, counts as absent (`bench_image_problem` says why, in one line naming the file).

Every decoding of a view picture opens it with `open_picture` (`decode_picture` decodes it):
the width and height are read from the file's header and checked against `MAX_IMAGE_PIXELS`
before a pixel is decoded, so a PNG of half a megabyte that would decode to gigabytes costs
nothing, and a file whose pixels do not decode (truncated) is refused in the same one line.
"""

from __future__ import annotations

import io
import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, NamedTuple

from .._errors import PictureError
from ..semantics import Machine
from ._fs import Location, confined, location
from ._layout import image_paths, not_a_file_name, relative_inside

if TYPE_CHECKING:
    from PIL import Image

MAX_IMAGE_BYTES = 64 << 20
"""A view image file larger than this is not read (it counts as absent)."""
MAX_IMAGE_PIXELS = 1 << 24
"""A view image of more pixels than this (width x height, 4096 x 4096; read from the file's
header) is not decoded (it counts as absent): decoded, it takes up to 4 bytes a pixel, 64 MiB,
where Pillow's own bomb threshold (178,956,970 pixels) lets 700 MB through."""

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


def _plugin(head: bytes):
    """Pillow's reader of the picture format `head` starts with (PNG, JPEG or WebP), or None.
    Only these three are ever opened, by their own plugin: no other format's code runs on
    a benchmark's bytes."""
    if head.startswith(b"\x89PNG\r\n\x1a\n"):
        from PIL.PngImagePlugin import PngImageFile

        return PngImageFile
    if head.startswith(b"\xff\xd8\xff"):
        from PIL.JpegImagePlugin import JpegImageFile

        return JpegImageFile
    if head.startswith(b"RIFF") and head[8:12] == b"WEBP":
        from PIL.WebPImagePlugin import WebPImageFile

        return WebPImageFile
    return None


def open_picture(data: bytes, name: str = "picture") -> Image.Image:
    """The picture `data` holds, opened but not decoded (decoding starts at its first use:
    `convert`, `load`, `resize`...), once its header shows a PNG, JPEG or WebP picture of at
    most `MAX_IMAGE_PIXELS` pixels; else `PictureError`, one line naming `name`. Every
    decoding of a view picture starts here (PROTOCOL §1.1)."""
    plugin = _plugin(data[:12])
    if plugin is None:
        raise PictureError(name, "not a PNG, JPEG or WebP picture")
    try:
        img = plugin(io.BytesIO(data))  # reads the header only
    except (OSError, SyntaxError, ValueError, IndexError, TypeError, EOFError) as exc:
        raise PictureError(name, f"not a readable {plugin.format} picture ({exc})") from None
    width, height = img.size
    if width * height > MAX_IMAGE_PIXELS:
        img.close()
        raise PictureError(
            name,
            f"a picture of {width:,} x {height:,} pixels, more than the {MAX_IMAGE_PIXELS:,} "
            "a view picture may have (PROTOCOL §1.1): not decoded",
        )
    return img


def decode_picture(data: bytes, name: str = "picture") -> Image.Image:
    """The picture decoded as RGB, once `open_picture` lets it through; `PictureError` naming
    `name` when it is refused there or when its pixels do not decode (a truncated or corrupt
    file whose header is sound)."""
    with open_picture(data, name) as img:
        try:
            return img.convert("RGB")
        except (OSError, SyntaxError, ValueError, IndexError, EOFError) as exc:
            raise PictureError(name, f"not a readable {img.format} picture ({exc})") from None


def view_image_of(data: bytes, name: str = "picture") -> ViewImage:
    """Bytes as a `ViewImage` (format and size from the file's header, nothing decoded), or
    `PictureError` naming `name` when `open_picture` refuses them."""
    with open_picture(data, name) as img:
        return ViewImage(data, _FORMATS[img.format or ""], *img.size)


def decode_view_image(data: bytes) -> ViewImage | None:
    """Bytes as a `ViewImage` (format and size from the file's header), or None when they are
    not a PNG, JPEG or WebP picture of at most `MAX_IMAGE_PIXELS` pixels."""
    try:
        return view_image_of(data)
    except PictureError:
        return None


def _read(path: Location) -> ViewImage | None:
    """The picture at `path`; None when there is no file; `PictureError` naming it when the
    file is too large or not a picture."""
    try:
        if not path.is_file():
            return None
        with path.open_read() as fh:
            data = fh.read(MAX_IMAGE_BYTES + 1)
    except OSError:
        return None
    if len(data) > MAX_IMAGE_BYTES:
        raise PictureError(str(path), f"more than {MAX_IMAGE_BYTES:,} bytes: not read")
    return view_image_of(data, str(path))


def _candidates(root: Location, machine: Machine, view: str) -> Iterator[Location]:
    """The files that may hold the view's picture, in the order of PROTOCOL §1.1. Only a file
    inside BENCH: a view that cannot name a file, an `images` path that leaves BENCH
    (absolute, `..`, a link out) is no candidate."""
    view = view.lower()
    if not_a_file_name(view) is None:
        for path in image_paths(root, machine.device_id, view):
            if _present(path) and confined(root, path):
                yield path
    ref = machine.images.get(view)
    if ref is not None and relative_inside(ref[0]) and confined(root, root / ref[0]):
        yield root / ref[0]


def _present(path: Location) -> bool:
    """Whether a local path names anything, a dangling link included (one `lstat`: most
    views have no file, and `confined` resolves every folder of a path); True in a store."""
    return path.local is None or os.path.lexists(path.local)


def bench_image(bench: str | Location, machine: Machine, view: str) -> ViewImage | None:
    """The benchmark's own picture of `view` (PROTOCOL §1.1 order), or None."""
    for path in _candidates(location(bench), machine, view):
        try:
            found = _read(path)
        except PictureError:
            continue  # too large or not a picture: absent (`bench_image_problem` says why)
        if found is not None:
            return found
    return None


def bench_image_problem(bench: str | Location, machine: Machine, view: str) -> PictureError | None:
    """Why the benchmark's own picture of `view` is not shown: the refusal (one line naming
    the file) of the first file of the §1.1 order that is there but too large or not a
    picture; None when a picture is shown, or when there is no file at all."""
    first: PictureError | None = None
    for path in _candidates(location(bench), machine, view):
        try:
            if _read(path) is not None:
                return None
        except PictureError as exc:
            first = first or exc
    return first


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
    "MAX_IMAGE_PIXELS",
    "BenchImages",
    "ImageSource",
    "ViewImage",
    "as_view_image",
    "bench_image",
    "bench_image_problem",
    "decode_picture",
    "decode_view_image",
    "open_picture",
    "view_image_of",
]
