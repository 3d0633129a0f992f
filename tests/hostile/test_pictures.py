"""Pictures small on disk and huge once decoded (issue 25): a PNG of 13,370 x 13,370 pixels,
half a megabyte, just under Pillow's bomb threshold, took 1.64 GB in the export and 1.78 GB
in the dashboard's episode viewer. Every decoder now reads the header first and refuses a
picture past `replay.MAX_IMAGE_PIXELS` (PROTOCOL §1.1): it counts as absent, `vge validate`
names its file in one line, and the dashboard's stand-in says why.

Each reader runs as a real process under an address-space bound (`tests.bounded`), once on
the kettle benchmark with its usual small picture and once with the huge one in its place:
the huge one may not cost more than a few MB over the small one.
"""

from __future__ import annotations

import io
import sys
from pathlib import Path

import pytest

import replay
from tests.bounded import Finished, run_bounded

from .picture_inputs import (
    BOMB_SIDE,
    ENV_SCRIPT,
    FRONT,
    VIEWER_SCRIPT,
    huge_png,
    picture_bench,
)

VGE = [sys.executable, "-m", "vge_analytics.cli"]
MiB = 1 << 20
ALLOWANCE = 48 * MiB
"""What the huge picture may cost over the small one: far below its 536 MB of pixels."""


@pytest.fixture(scope="module")
def huge(tmp_path_factory: pytest.TempPathFactory) -> bytes:
    path = huge_png(tmp_path_factory.mktemp("png") / "huge.png", BOMB_SIDE)
    data = path.read_bytes()
    assert len(data) < 1 * MiB  # small on disk, 536 MB as RGB
    return data


@pytest.fixture(scope="module")
def sides(tmp_path_factory: pytest.TempPathFactory, huge: bytes) -> dict[str, Path]:
    """The same benchmark and run with the small picture (`small`) and the huge one (`huge`)."""
    return {
        "small": picture_bench(tmp_path_factory.mktemp("small"), None),
        "huge": picture_bench(tmp_path_factory.mktemp("huge"), huge),
    }


def _vge(*args: object) -> Finished:
    return run_bounded([*VGE, *map(str, args)], timeout=120.0)


def _python(code: str, *args: object) -> Finished:
    return run_bounded([sys.executable, "-c", code, *map(str, args)], timeout=120.0)


def _both(run) -> dict[str, Finished]:
    done = {name: run(name) for name in ("small", "huge")}
    for finished in done.values():
        assert finished.returncode == 0, finished.stderr
    assert done["huge"].peak_memory < done["small"].peak_memory + ALLOWANCE, {
        name: f.peak_memory // MiB for name, f in done.items()
    }
    return done


def _replayed(root: Path) -> Path:
    out = root / "out"
    if not out.exists():
        done = _vge("replay", root / "run", "--bench", root / "bench", "--out", out, "--mcap")
        assert done.returncode == 0, done.stderr
    return out


def test_the_header_is_read_and_nothing_decoded(huge: bytes) -> None:
    with pytest.raises(replay.PictureError) as refused:
        replay.io.open_picture(huge, "BENCH/images/kettle/front.png")
    assert str(refused.value) == (
        "BENCH/images/kettle/front.png: a picture of 13,370 x 13,370 pixels, more than the "
        "16,777,216 a view picture may have (PROTOCOL §1.1): not decoded"
    )
    assert replay.io.decode_view_image(huge) is None


def _camera_frames(path: Path) -> list[bytes]:
    """The pictures of the `/camera` topic of an episode's MCAP file."""
    from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
    from mcap.reader import make_reader

    frames = []
    with open(path, "rb") as fh:
        for _, channel, message in make_reader(fh).iter_messages():
            if channel.topic == "/camera":
                frames.append(CompressedImage.FromString(message.data).data)
    return frames


def _warnings(done: Finished) -> list[str]:
    text = done.stderr if isinstance(done.stderr, str) else done.stderr.decode()
    return [line for line in text.splitlines() if line.startswith("warning:")]


def _refused(sides, fate: str) -> str:
    """The one line saying the huge picture is left out, as `vge validate` names it."""
    return (
        f"warning: {sides['huge'] / 'bench' / FRONT} [view front]: a picture of 13,370 x "
        "13,370 pixels, more than the 16,777,216 a view picture may have (PROTOCOL §1.1): "
        f"not decoded; {fate}"
    )


def test_mcap_replay_in_bounded_memory(sides) -> None:
    def replay_mcap(name: str) -> Finished:
        root = sides[name]
        out = root / "out-mcap"
        return _vge("replay", root / "run", "--bench", root / "bench", "--out", out, "--mcap")

    done = _both(replay_mcap)
    assert _warnings(done["small"]) == []
    assert _warnings(done["huge"]) == [_refused(sides, "left out of the MCAP files")]
    frames = {
        name: _camera_frames(replay.episode_mcap_path(root / "out-mcap", "r", "e1").local)
        for name, root in sides.items()
    }
    # the small picture is the step's frame; the huge one is absent: no frame, nothing decoded
    assert frames["small"] == [(sides["small"] / "bench" / FRONT).read_bytes()]
    assert frames["huge"] == []


def test_export_in_bounded_memory(sides) -> None:
    def export(name: str) -> Finished:
        out = _replayed(sides[name])
        return _vge("export", out, "--format", "atif", "--out", sides[name] / "atif")

    done = _both(export)
    assert _warnings(done["small"]) == []
    assert _warnings(done["huge"]) == [_refused(sides, "left out of the export")]
    pictures = {
        n: list((root / "atif" / "r" / "images").glob("*.jpg")) for n, root in sides.items()
    }
    assert len(pictures["small"]) == 1
    assert pictures["huge"] == []  # the step goes without its picture


def test_dashboard_viewer_in_bounded_memory(sides) -> None:
    done = _both(lambda name: _python(VIEWER_SCRIPT, _replayed(sides[name])))
    assert done["small"].stdout_head.decode().split()[1:] == ["True", "None"]
    shown = done["huge"].stdout_head.decode()
    assert shown.split()[1] == "False"
    assert f"{sides['huge'] / 'bench' / FRONT}: a picture of 13,370 x 13,370 pixels" in shown


def test_environment_in_bounded_memory(sides) -> None:
    done = _both(lambda name: _python(ENV_SCRIPT, sides[name] / "bench"))
    assert done["small"].stdout_head.decode().split() == ["200", "30", "30"]  # the red picture
    assert done["huge"].stdout_head.decode().split() == ["236", "238", "242"]  # the canvas


def test_validate_names_the_picture_in_one_line(sides) -> None:
    done = _vge("validate", sides["huge"] / "bench")
    warnings = [line for line in done.stdout_head.decode().splitlines() if FRONT in line]
    assert warnings == [
        f"warning {sides['huge'] / 'bench' / FRONT} [view front]: a picture of 13,370 x "
        "13,370 pixels, more than the 16,777,216 a view picture may have (PROTOCOL §1.1): "
        "not decoded"
    ], done.stdout_head.decode()
    assert FRONT not in _vge("validate", sides["small"] / "bench").stdout_head.decode()


def test_a_drawn_step_of_a_huge_picture_is_the_stand_in_saying_why(huge: bytes) -> None:
    """A picture that reaches `draw_step` by another way than `view_picture` (a source that
    does not check) is still opened by its header first: the stand-in, with the reason."""
    from PIL import Image

    from vge_analytics import dashboard as dash

    picture = dash.ViewPicture(huge, "png", BOMB_SIDE, BOMB_SIDE, rendered=True)
    with Image.open(io.BytesIO(dash.draw_step(picture, [], None))) as drawn:
        assert drawn.size == (600, 600)  # the stand-in's canvas, not 720 wide
        grey = drawn.convert("RGB").getcolors(600 * 600)
    assert grey is not None and max(grey)[1] == (236, 238, 242)
    assert len(grey) > 1  # the reason is written on it


def _truncated_png() -> bytes:
    """A picture of 640 x 480 whose header is sound and whose pixels stop half-way."""
    from PIL import Image

    buf = io.BytesIO()
    Image.new("RGB", (640, 480), (200, 30, 30)).save(buf, format="PNG")
    return buf.getvalue()[: len(buf.getvalue()) // 2]


def test_a_truncated_picture_is_refused_in_one_line_everywhere_it_is_decoded(tmp_path) -> None:
    from PIL import Image

    from replay.env import DeviceEnv
    from vge_analytics import dashboard as dash
    from vge_analytics.export._pictures import shrink

    data = _truncated_png()
    assert replay.io.decode_view_image(data) == replay.ViewImage(data, "png", 640, 480)
    with pytest.raises(replay.PictureError) as refused:
        replay.io.decode_picture(data, "BENCH/images/kettle/front.png")
    assert str(refused.value) == (
        "BENCH/images/kettle/front.png: not a readable PNG picture (image file is truncated)"
    )
    with pytest.raises(replay.PictureError):
        shrink(data)  # the export: the step goes without its picture
    drawn = dash.draw_step(dash.ViewPicture(data, "png", 640, 480, rendered=True), [], None)
    with Image.open(io.BytesIO(drawn)) as img:
        assert img.size == (600, 600)  # the stand-in
    root = picture_bench(tmp_path, data)
    env = DeviceEnv(str(root / "bench"), image_width=64, image_height=64)
    obs, _ = env.reset(options={"episode_id": "e1"})
    assert tuple(obs["image"][32, 32]) == (236, 238, 242)  # the canvas


def test_the_export_says_which_picture_it_left_out(tmp_path) -> None:
    """A picture whose header is sound but whose pixels stop half-way reaches the export (no
    reader before it decodes pixels); the export goes without it and says so in one line."""
    from vge_analytics.export import export

    root = picture_bench(tmp_path, _truncated_png())
    replay.replay_runs([str(root / "run")], str(root / "bench"), str(root / "out"), progress=False)
    summary = export(root / "out", "atif", root / "atif")
    assert summary.left_out == [
        "device kettle, view front: not a readable PNG picture (image file is truncated)"
    ]
    assert export(root / "out", "atif", root / "atif-text", images="none").left_out == []
