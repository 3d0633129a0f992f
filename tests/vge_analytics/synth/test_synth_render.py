"""Rendered views: deterministic, every component drawn inside its bbox, one image per view at
the SSM's size, and the image lookup order of `vge_analytics.synth.view_image`."""

from __future__ import annotations

import hashlib
import io
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from PIL import Image, ImageChops

import replay
from vge_analytics.synth import instantiate_device, view_image
from vge_analytics.synth._render import png_bytes, render_view

ROOT = Path(__file__).resolve().parents[3]


@pytest.fixture(autouse=True)
def _private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("VGE_CACHE_DIR", str(tmp_path / "cache"))


def _devices():
    # A dashboard microwave, a cylindrical kettle, and a small handheld device.
    microwaves = (instantiate_device("Microwave", f"Microwave_{i:03d}", 0) for i in range(12))
    out = [next(d for d in microwaves if d.geometry.panel is not None)]
    out.append(instantiate_device("ElectricKettle", "ElectricKettle_001", 0))
    return out


RENDERED = {
    "front": "00575aab85b7636012cbcb758d2fa052c59143d8b133336edd0dfb4c9e346e86",
    "front_top": "8c1e16ec7f172fd0b711b0831c81712cbf27342a9ea39fe92541d336980975cc",
    "dashboard": "f4583029cfa920ffbb68d3001b0b78b48aab624c3a77f21588e82036038f8bfb",
}
"""sha256 of the PNG bytes of three views of Microwave_001 (seed 0), the first microwave with
a dashboard. The MCAP digest of tests/replay/io/test_sample_digest.py holds these pictures
too; a deliberate change of the drawing records both again, with the reason in the commit."""


def rendered_digests() -> dict[str, str]:
    """The digests of `RENDERED`, computed in this process."""
    device = _devices()[0]
    assert device.device_id == "Microwave_001"
    return {
        view: hashlib.sha256(png_bytes(render_view(device.geometry, view))).hexdigest()
        for view in RENDERED
    }


def test_rendering_gives_the_recorded_bytes():
    assert rendered_digests() == RENDERED


@pytest.mark.parametrize("hash_seed", ["0", "4242"])
def test_rendering_gives_the_recorded_bytes_in_another_process(hash_seed):
    # A fresh interpreter with another string-hash seed: no set or dict order, no state left
    # by this process, can reach the pictures.
    code = (
        "import json\n"
        "from tests.vge_analytics.synth.test_synth_render import rendered_digests\n"
        "print(json.dumps(rendered_digests()))"
    )
    done = subprocess.run(
        [sys.executable, "-c", code],
        cwd=ROOT,
        env={**os.environ, "PYTHONHASHSEED": hash_seed},
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout) == RENDERED


def test_every_view_has_the_ssm_size():
    for device in _devices():
        g = device.geometry
        sizes = {}
        for per_view in g.bboxes().values():
            for view, coord in per_view.items():
                sizes[view] = (coord[4], coord[5])
        for view in list(g.frames) + list(g.axo_frames) + (["dashboard"] if g.panel else []):
            img = render_view(g, view)
            if view in sizes:
                assert img.size == sizes[view], (device.device_id, view)
            assert 400 <= img.size[0] <= 1420 and 400 <= img.size[1] <= 1420


def test_components_are_drawn_inside_their_bboxes():
    for device in _devices():
        g = device.geometry
        full_views = {}
        for part in g.parts:
            for view in part.views:
                if view not in full_views:
                    full_views[view] = render_view(g, view)
                full = full_views[view]
                without = render_view(g, view, omit=frozenset({part.name}))
                diff = ImageChops.difference(full, without).getbbox()
                assert diff is not None, f"{part.name} not drawn in {view}"
                x0, y0, x1, y1 = g.part_rect(part, view)
                assert x0 <= diff[0] and y0 <= diff[1] and diff[2] <= x1 and diff[3] <= y1, (
                    device.device_id,
                    part.name,
                    view,
                    diff,
                    (x0, y0, x1, y1),
                )


def _bench_with(tmp_path: Path, device) -> tuple[Path, replay.Machine]:
    from vge_analytics.synth import dump_ssm

    bench = tmp_path / "bench"
    (bench / "ssm").mkdir(parents=True)
    path = bench / "ssm" / f"{device.device_id}.json"
    path.write_text(dump_ssm(device.ssm), encoding="utf-8")
    return bench, replay.load_machine(path)


def test_view_image_renders_and_caches_synthetic_views(tmp_path):
    device = _devices()[0]
    bench, machine = _bench_with(tmp_path, device)
    first = view_image(bench, machine, "front")
    assert first is not None and first.format == "png"
    assert (first.width, first.height) == device.geometry.view_size("front")
    cached = list((tmp_path / "cache").rglob("front.png"))
    assert len(cached) == 1
    again = view_image(bench, machine, "front")
    assert again == first
    with Image.open(io.BytesIO(first.data)) as img:
        assert img.size == (first.width, first.height)


def test_view_image_prefers_files_then_the_images_extension(tmp_path):
    device = _devices()[1]
    bench, machine = _bench_with(tmp_path, device)
    # PROTOCOL §1.1 file wins.
    folder = bench / "images" / device.device_id
    folder.mkdir(parents=True)
    buf = io.BytesIO()
    Image.new("RGB", (64, 48), (1, 2, 3)).save(buf, format="JPEG")
    (folder / "front.jpg").write_bytes(buf.getvalue())
    got = view_image(bench, machine, "front")
    assert got is not None and got.format == "jpeg" and (got.width, got.height) == (64, 48)
    # The SSM's images extension comes next.
    raw = json.loads((bench / "ssm" / f"{device.device_id}.json").read_text())
    Image.new("RGB", (30, 20)).save(bench / "top_custom.png")
    raw["images"] = {"top": {"path": "top_custom.png", "width": 30, "height": 20}}
    path = bench / "ssm" / f"{device.device_id}.json"
    path.write_text(json.dumps(raw))
    machine = replay.load_machine(path)
    got = view_image(bench, machine, "top")
    assert got is not None and (got.width, got.height) == (30, 20)
    # Views without a file fall back to the synthetic rendering, unknown views to None.
    assert view_image(bench, machine, "left") is not None
    assert view_image(bench, machine, "dashboard") is None


def test_hand_written_ssm_of_our_category_is_drawn_from_its_bboxes(tmp_path):
    """The paper's kettle listing: not produced by our layout, drawn at its own bboxes."""
    machine = replay.load_machine(ROOT / "tests" / "data" / "kettle_ssm.json")
    got = view_image(tmp_path, machine, "front")
    assert got is not None and (got.width, got.height) == (1209, 1369)
    for view in machine.views:
        assert view_image(tmp_path, machine, view) is not None


def test_unknown_category_has_no_image(tmp_path):
    src = ROOT / "tests" / "data" / "hand_worked" / "dashboard_ssm.json"
    shutil.copy(src, tmp_path / "oven.json")
    machine = replay.load_machine(tmp_path / "oven.json")
    assert view_image(tmp_path, machine, "front") is None
