"""The view images of a device, wherever they come from.

`view_image` looks, in order, at `BENCH/images/<device_id>/<view>.png|jpg` (PROTOCOL §1.1), at the
SSM's `images` extension, and finally, for devices of the synthetic categories, renders the view
(`vge_analytics.synth`) and caches the PNG on disk. The cache lives under `$VGE_CACHE_DIR`, else
`$XDG_CACHE_HOME/vge-analytics`, else `~/.cache/vge-analytics`, keyed by a hash of the SSM, the
renderer and the category data; files are written to a temporary name and renamed, so
concurrent processes never read a half-written image.
"""

from __future__ import annotations

import hashlib
import io
import os
import tempfile
import threading
from dataclasses import dataclass
from pathlib import Path

import msgspec
from PIL import Image

import replay

_FORMATS = {".png": "png", ".jpg": "jpeg", ".jpeg": "jpeg"}


@dataclass(frozen=True, slots=True)
class ViewImage:
    """One view of a device as an encoded image."""

    data: bytes
    format: str
    """`png` or `jpeg`."""
    width: int
    height: int


def cache_dir() -> Path:
    """Where rendered synthetic views are cached."""
    explicit = os.environ.get("VGE_CACHE_DIR")
    if explicit:
        return Path(explicit)
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg) if xdg else Path.home() / ".cache"
    return base / "vge-analytics"


def _from_file(path: Path | replay.Location) -> ViewImage | None:
    try:
        data = path.read_bytes()
    except OSError:
        return None
    try:
        with Image.open(io.BytesIO(data)) as img:
            width, height = img.size
            fmt = (img.format or "").lower()
    except (OSError, ValueError):
        return None
    fmt = {"jpeg": "jpeg", "png": "png"}.get(fmt, _FORMATS.get(path.suffix.lower(), fmt))
    return ViewImage(data, fmt, width, height)


def view_image(
    bench_root: str | Path | replay.Location, machine: replay.Machine, view: str
) -> ViewImage | None:
    """The image of `view` for this device (the benchmark a path or a URI), or None when
    there is none."""
    view = view.lower()
    root = replay.location(bench_root)
    folder = root / "images" / machine.device_id
    for ext in (".png", ".jpg", ".jpeg"):
        path = folder / f"{view}{ext}"
        if path.is_file():
            found = _from_file(path)
            if found is not None:
                return found
    ref = machine.images.get(view)
    if ref is not None:
        found = _from_file(root / ref[0])
        if found is not None:
            return found
    return synthetic_view(machine, view)


def synthetic_view(machine: replay.Machine, view: str) -> ViewImage | None:
    """A rendering of the view when the device belongs to a synthetic category (cached)."""
    from vge_analytics.synth import _catalog

    view = view.lower()
    if view not in machine.views or not _catalog.is_known_category(machine.category):
        return None
    key = _cache_key(machine)
    path = cache_dir() / "views" / key[:2] / key / f"{view}.png"
    if path.is_file():
        found = _from_file(path)
        if found is not None:
            return found
    data = _render_png(machine, view, key)
    _store(path, data)
    with Image.open(io.BytesIO(data)) as img:
        width, height = img.size
    return ViewImage(data, "png", width, height)


def _cache_key(machine: replay.Machine) -> str:
    from vge_analytics.synth import _catalog, _layout, _render

    h = hashlib.sha256()
    for part in (
        _render.RENDER_VERSION,
        _layout.LAYOUT_VERSION,
        machine.device_id,
        machine.category,
        _catalog.data_digest(machine.category),
    ):
        h.update(part.encode("utf-8"))
        h.update(b"\0")
    h.update(msgspec.json.encode(machine.ssm))
    return h.hexdigest()


_SCENES: dict[str, object] = {}
_SCENES_MAX = 64
_SCENES_LOCK = threading.Lock()


def _scene(key: str, machine: replay.Machine):
    """The layout of a synthetic SSM, or None when the SSM is not one the layout reproduces
    (kept for the last few devices: the views of one device are usually asked together)."""
    with _SCENES_LOCK:
        if key in _SCENES:
            return _SCENES[key]
    from vge_analytics.synth._instantiate import scene_of

    geometry = scene_of(machine.ssm, machine.device_id)
    with _SCENES_LOCK:
        if len(_SCENES) >= _SCENES_MAX:
            _SCENES.pop(next(iter(_SCENES)))
        _SCENES[key] = geometry
    return geometry


def _render_png(machine: replay.Machine, view: str, key: str) -> bytes:
    from vge_analytics.synth import _foreign, _render

    geometry = _scene(key, machine)
    if geometry is not None:
        img = _render.render_view(geometry, view)
    else:
        img = _foreign.render_foreign(machine.ssm, machine.category, view)
    return _render.png_bytes(img)


def _store(path: Path, data: bytes) -> None:
    """Write atomically; a cache that cannot be written is simply skipped."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=".tmp-", suffix=".png", dir=path.parent)
        try:
            with os.fdopen(fd, "wb") as fh:
                fh.write(data)
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
    except OSError:
        return


__all__ = ["ViewImage", "cache_dir", "synthetic_view", "view_image"]
