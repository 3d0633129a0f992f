"""Hostile pictures, generated (never stored): PNGs small on disk and huge once decoded.
Shared by `tests/hostile/test_pictures.py` and `benchmarks/bench_hostile.py`.

A PNG of one colour compresses about a thousandfold, so `huge_png(path, 13370)` writes a
picture of 178,756,900 pixels (just under Pillow's bomb threshold of 178,956,970) in about
half a megabyte, row by row: building it never holds the pixels.
"""

from __future__ import annotations

import io
import json
import struct
import zlib
from pathlib import Path

KETTLE = Path(__file__).resolve().parents[1] / "data" / "kettle_ssm.json"
FRONT = "images/kettle/front.png"
"""Where `picture_bench` puts the picture of the kettle's front view, under BENCH."""

BOMB_SIDE = 13370
"""Side of the square just under Pillow's default bomb threshold (2 x 89,478,485 pixels)."""

_COLOR_TYPES = {"rgb": (2, 3), "palette": (3, 1)}
"""Mode -> (PNG colour type, bytes per pixel at 8 bits)."""


def _chunk(kind: bytes, body: bytes) -> bytes:
    return (
        struct.pack(">I", len(body))
        + kind
        + body
        + struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF)
    )


def huge_png(path: Path, width: int, height: int | None = None, *, mode: str = "rgb") -> Path:
    """A PNG of `width` x `height` (square by default) pixels of one grey, 8 bits per
    sample, `rgb` or `palette`, written without holding its pixels."""
    height = width if height is None else height
    color_type, channels = _COLOR_TYPES[mode]
    row = b"\0" + b"\x80" * (width * channels)  # filter byte "none", then the pixels
    packer = zlib.compressobj(9)
    parts = [b"\x89PNG\r\n\x1a\n"]
    parts.append(_chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, color_type, 0, 0, 0)))
    if mode == "palette":
        parts.append(_chunk(b"PLTE", b"\x80\x80\x80" * 256))
    data = bytearray()
    for _ in range(height):
        data += packer.compress(row)
    data += packer.flush()
    parts.append(_chunk(b"IDAT", bytes(data)))
    parts.append(_chunk(b"IEND", b""))
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(b"".join(parts))
    return path


def picture_bench(root: Path, picture: bytes | None) -> Path:
    """Under `root`: `bench`, the kettle benchmark with one task and the front view's picture
    `picture` (a small red one of 640 x 480 when None), and `run`, a run of one step. The
    kettle's category is one the analytics do not render, so a refused picture is absent
    everywhere rather than replaced by a rendering."""
    from PIL import Image

    bench = root / "bench"
    (bench / "ssm").mkdir(parents=True)
    ssm = json.loads(KETTLE.read_text())
    ssm["category"] = "HostileKettle"
    (bench / "ssm" / "kettle.json").write_text(json.dumps(ssm))
    task = {
        "episode_id": "e1",
        "device_id": "kettle",
        "goals": ["Boiling"],
        "initial_view": "front",
    }
    (bench / "tasks.jsonl").write_text(json.dumps(task) + "\n")
    (bench / FRONT).parent.mkdir(parents=True)
    if picture is None:
        buf = io.BytesIO()
        Image.new("RGB", (640, 480), (200, 30, 30)).save(buf, format="PNG")
        picture = buf.getvalue()
    (bench / FRONT).write_bytes(picture)
    run = root / "run"
    run.mkdir()
    (run / "run.json").write_text(json.dumps({"run_id": "r", "model": "m", "agent_kind": "vlm"}))
    step = {"output": "Thinking: wait.\nAction: Timed_wait()"}
    (run / "episodes.jsonl").write_text(json.dumps({"episode_id": "e1", "steps": [step]}) + "\n")
    return root


VIEWER_SCRIPT = """
import sys
from vge_analytics import dashboard as dash
png = dash.step_picture(sys.argv[1], "r", "e1", 0)
picture = dash.view_picture(sys.argv[1], "kettle", "front")
print(len(png), picture.rendered, picture.problem)
"""
"""What the episode viewer and the grounding page do with the picture of step 0 (argv: OUT)."""


ENV_SCRIPT = """
import sys
from replay.env import DeviceEnv
env = DeviceEnv(sys.argv[1], image_width=256, image_height=256)
obs, _ = env.reset(options={"episode_id": "e1"})
print(*obs["image"][128, 128])
"""
"""The environment's first observation (argv: BENCH): the colour of its middle pixel."""
