"""`vge synth` end to end on the tiny scale, the full-scale plan, and `--images` rendering."""

from __future__ import annotations

import json

from PIL import Image

import replay
from vge_analytics.cli import main
from vge_analytics.synth import PAPER_DEVICE_COUNTS, SCALES, available_categories, plan_devices
from vge_analytics.synth._prerender import render_device


def test_vge_synth_tiny(tmp_path):
    out = tmp_path / "synth"
    assert (
        main(["synth", "--out", str(out), "--scale", "tiny", "--seed", "3", "--workers", "1"]) == 0
    )
    meta = json.loads((out / "synth.json").read_text())
    assert meta["scale"] == "tiny" and meta["seed"] == 3
    assert (out / "bench" / "tasks.jsonl").exists()
    runs = sorted(p.name for p in (out / "runs").iterdir())
    assert {"sim-vlm-a", "sim-vlm-f", "sim-human"} <= set(runs)
    assert all((out / "runs" / r / "episodes.jsonl.gz").exists() for r in runs)
    assert replay.validate_benchmark(out / "bench") == []
    # A second run replaces the earlier output; a foreign directory is refused.
    assert main(["synth", "--out", str(out), "--scale", "tiny", "--workers", "1"]) == 0
    foreign = tmp_path / "foreign"
    (foreign / "bench").mkdir(parents=True)
    assert main(["synth", "--out", str(foreign), "--scale", "tiny"]) == 1


def test_unknown_scale_is_a_clear_error(tmp_path, capsys):
    assert main(["synth", "--out", str(tmp_path / "x"), "--scale", "huge"]) == 1
    assert (
        capsys.readouterr().err == "error: --scale must be one of tiny, sample, full, not 'huge'\n"
    )
    assert not (tmp_path / "x").exists()  # refused before anything is written


def test_full_scale_plan_matches_the_paper():
    jobs = plan_devices(SCALES["full"], 0)
    assert len(jobs) == sum(PAPER_DEVICE_COUNTS[c] for c in available_categories())
    if len(available_categories()) == len(PAPER_DEVICE_COUNTS):
        assert len(jobs) == 968
        assert sum(j.n_single for j in jobs) == 4948
        assert sum(j.n_multi for j in jobs) == 10005
    for cat in available_categories():
        assert sum(j.category == cat for j in jobs) == PAPER_DEVICE_COUNTS[cat]


def test_prerender_writes_every_view(tmp_path):
    from vge_analytics.synth import dump_ssm, instantiate_device

    device = instantiate_device("ElectricKettle", "ElectricKettle_000", 0)
    path = tmp_path / "ElectricKettle_000.json"
    path.write_text(dump_ssm(device.ssm), encoding="utf-8")
    count = render_device(path, tmp_path / "images")
    files = sorted((tmp_path / "images" / "ElectricKettle_000").glob("*.png"))
    assert count == len(files) == 8
    with Image.open(tmp_path / "images" / "ElectricKettle_000" / "front.png") as img:
        assert img.size == device.geometry.view_size("front")
