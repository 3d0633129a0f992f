"""The view images of a device, wherever they come from.

`image_source(bench)` is the one image source of the analytics, the CLI, the dashboard and
the live tools: the benchmark's own pictures by the replay's resolver (`replay.BenchImages`,
PROTOCOL §1.1), else, for devices of the synthetic categories, a rendering of the view
(this package's renderer), cached as PNG on disk. The cache lives under `$VGE_CACHE_DIR`, else
`$XDG_CACHE_HOME/vge-analytics`, else `~/.cache/vge-analytics`, keyed by a hash of the SSM,
the renderer and the category data; files are written to a temporary name and renamed, so
concurrent processes never read a half-written image.
"""

from __future__ import annotations

import hashlib
import os
import threading
from pathlib import Path

import msgspec

import replay
from replay import ViewImage
from replay.io import write_atomic

from ._catalog import data_digest, is_known_category
from ._foreign import render_foreign
from ._instantiate import scene_of
from ._layout import LAYOUT_VERSION
from ._render import RENDER_VERSION, png_bytes, render_view


def cache_dir() -> Path:
    """Where rendered synthetic views are cached."""
    explicit = os.environ.get("VGE_CACHE_DIR")
    if explicit:
        return Path(explicit)
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg) if xdg else Path.home() / ".cache"
    return base / "vge-analytics"


def image_source(bench: str | Path | replay.Location) -> replay.BenchImages:
    """The pictures of a benchmark's views (a path or a URI): its own, else the rendered
    synthetic ones (picklable, for `replay_runs` with workers)."""
    return replay.BenchImages(str(bench), fallback=synthetic_view)


def view_image(
    bench: str | Path | replay.Location, machine: replay.Machine, view: str
) -> ViewImage | None:
    """The picture of `view` for this device, or None when there is none."""
    return image_source(bench)(machine, view)


def synthetic_view(machine: replay.Machine, view: str) -> ViewImage | None:
    """A rendering of the view when the device belongs to a synthetic category (cached)."""
    view = view.lower()
    if view not in machine.views or not is_known_category(machine.category):
        return None
    key = _cache_key(machine)
    path = cache_dir() / "views" / key[:2] / key / f"{view}.png"
    found = _cached(path)
    if found is not None:
        return found
    data = _render_png(machine, view, key)
    _store(path, data)
    return replay.io.view_image_of(data)


def _cached(path: Path) -> ViewImage | None:
    """The cached rendering, when it is there and a picture within the bounds of any view
    picture (`replay.io.MAX_IMAGE_BYTES`, `MAX_IMAGE_PIXELS`): the cache is a folder anyone
    with the user's rights can write into."""
    try:
        if not path.is_file():  # not a pipe, which would never end
            return None
        with open(path, "rb") as fh:
            data = fh.read(replay.io.MAX_IMAGE_BYTES + 1)
    except OSError:
        return None
    return replay.io.decode_view_image(data) if len(data) <= replay.io.MAX_IMAGE_BYTES else None


def _cache_key(machine: replay.Machine) -> str:
    h = hashlib.sha256()
    for part in (
        RENDER_VERSION,
        LAYOUT_VERSION,
        machine.device_id,
        machine.category,
        data_digest(machine.category),
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
    geometry = scene_of(machine.ssm, machine.device_id)
    with _SCENES_LOCK:
        if len(_SCENES) >= _SCENES_MAX:
            _SCENES.pop(next(iter(_SCENES)))
        _SCENES[key] = geometry
    return geometry


def _render_png(machine: replay.Machine, view: str, key: str) -> bytes:
    geometry = _scene(key, machine)
    if geometry is not None:
        img = render_view(geometry, view)
    else:
        img = render_foreign(machine.ssm, machine.category, view)
    return png_bytes(img)


def _store(path: Path, data: bytes) -> None:
    """Write atomically (a cache: not synced); a cache that cannot be written is simply
    skipped."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        write_atomic(path, data, sync=False)
    except OSError:
        return


__all__ = ["cache_dir", "image_source", "synthetic_view", "view_image"]
