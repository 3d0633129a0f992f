"""What a benchmark names is read from the benchmark (PROTOCOL §1.1, §1.5): a task's device
id is never made a path unless it is one file name, and an SSM, a picture or tasks.jsonl that
leaves BENCH (an absolute path, `..`, a link out) is never read."""

from __future__ import annotations

import io
import json
from pathlib import Path

import pytest
from PIL import Image

import replay
from replay.io import bench_image

from .outcomes import counts, one_line_error
from .replay_inputs import episode, line_ssm, task, write_bench, write_run


def errors(stdout: str) -> list[str]:
    return [line for line in stdout.splitlines() if line.startswith("error")]


def png(size: int = 4) -> bytes:
    buffer = io.BytesIO()
    Image.new("RGB", (size, size), "red").save(buffer, "PNG")
    return buffer.getvalue()


@pytest.mark.parametrize(
    ("device", "why"),
    [
        ("../outside", "holds '/', '\\' or a NUL byte"),
        ("d\0x", "holds '/', '\\' or a NUL byte"),
        ("..", "is not a name"),
    ],
    ids=["dot-dot", "nul", "parent"],
)
def test_a_device_id_that_is_not_a_file_name_is_never_a_path(
    device, why, tmp_path, vge_here
) -> None:
    # A valid SSM where '../outside' would lead: it must not be read, hashed nor played.
    (tmp_path / "outside.json").write_text(json.dumps(line_ssm(2)))
    tasks = [task("e0", "press", "S1"), task("e1", device, "S1"), task("e2", "press", "S1")]
    bench = write_bench(tmp_path / "bench", {"press": line_ssm(2)}, tasks)
    run = write_run(tmp_path / "run", [episode(f"e{i}") for i in range(3)])
    done = vge_here("validate", bench, run)
    assert errors(done.stdout) == [
        f"error   {bench / 'tasks.jsonl'}:2 [episode 'e1']: device {device!r} cannot name an "
        f"SSM file (it {why})"
    ]
    out = tmp_path / "out"
    done = vge_here("replay", run, "--bench", bench, "--out", out)
    assert done.returncode == 2, done.stderr
    (record,) = map(json.loads, (out / "quarantine.jsonl").read_text().splitlines())
    assert (record["line"], record["kind"]) == (2, "unknown_device")
    assert record["reason"] == (
        f"device {device!r} (tasks.jsonl line 2) cannot name an SSM file (it {why})"
    )
    assert counts(out).replayed == 2
    manifest = replay.read_manifest(out)
    assert manifest is not None
    assert list(manifest.runs[0].inputs.ssm) == ["press"]


def test_an_ssm_linked_out_of_the_benchmark_is_never_read(tmp_path, vge_here) -> None:
    (tmp_path / "elsewhere.json").write_text(json.dumps(line_ssm(2)))
    tasks = [task("e0", "press", "S1"), task("e1", "linked", "S1")]
    bench = write_bench(tmp_path / "bench", {"press": line_ssm(2)}, tasks)
    (bench / "ssm" / "linked.json").symlink_to(tmp_path / "elsewhere.json")
    run = write_run(tmp_path / "run", [episode("e0"), episode("e1")])
    where = "ssm/linked.json"
    done = vge_here("validate", bench, run)
    assert errors(done.stdout) == [
        f"error   {bench / 'ssm'} [device 'linked']: it has an SSM file {where} that links "
        "outside the benchmark directory",
        f"error   {bench / 'tasks.jsonl'}:2 [episode 'e1']: device 'linked' has an SSM file "
        f"{where} that links outside the benchmark directory",
    ]
    out = tmp_path / "out"
    done = vge_here("replay", run, "--bench", bench, "--out", out)
    assert done.returncode == 2, done.stderr
    manifest = replay.read_manifest(out)
    assert manifest is not None
    assert manifest.runs[0].inputs.ssm["linked"].sha256 is None  # not even hashed
    assert counts(out).replayed == 1


def test_tasks_linked_out_of_the_benchmark_are_refused_in_one_line(tmp_path, vge_here) -> None:
    bench = write_bench(tmp_path / "bench", {"press": line_ssm(2)}, [task("e0", "press", "S1")])
    (bench / "tasks.jsonl").rename(tmp_path / "tasks.jsonl")
    (bench / "tasks.jsonl").symlink_to(tmp_path / "tasks.jsonl")
    run = write_run(tmp_path / "run", [episode("e0")])
    done = vge_here("replay", run, "--bench", bench, "--out", tmp_path / "out")
    assert done.returncode == 1
    assert one_line_error(done.stderr) == (
        f"error: {bench / 'tasks.jsonl'}: resolves outside the benchmark directory (a link)"
    )


def _machine_with_images(bench: Path, images: dict[str, str]) -> replay.Machine:
    ssm = line_ssm(2)
    ssm["images"] = {view: {"path": path, "width": 4, "height": 4} for view, path in images.items()}
    write_bench(bench, {"press": ssm}, [task("e0", "press", "S1")])
    return replay.io.Benchmark.open(bench).machine("press")


def test_pictures_are_read_from_inside_the_benchmark_only(tmp_path, vge_here) -> None:
    (tmp_path / "secret.png").write_bytes(png())
    bench = tmp_path / "bench"
    (bench / "pictures").mkdir(parents=True)
    (bench / "pictures" / "inside.png").write_bytes(png())
    (bench / "pictures" / "link.png").symlink_to(tmp_path / "secret.png")
    refs = {
        "front": "pictures/inside.png",
        "back": str(tmp_path / "secret.png"),
        "left": "../secret.png",
        "right": "pictures/../../secret.png",
        "top": "pictures/link.png",
    }
    machine = _machine_with_images(bench, refs)
    shown = {view: bench_image(bench, machine, view) for view in refs}
    assert {view: got is not None for view, got in shown.items()} == {
        "front": True,
        "back": False,
        "left": False,
        "right": False,
        "top": False,
    }
    # BENCH/images/<device>/<view>.png linked out of BENCH is not read either.
    (bench / "images" / "press").mkdir(parents=True)
    (bench / "images" / "press" / "bottom.png").symlink_to(tmp_path / "secret.png")
    assert bench_image(bench, machine, "bottom") is None

    done = vge_here("validate", bench)
    ssm = bench / "ssm" / "press.json"
    assert errors(done.stdout) == [
        f"error   {ssm} [images.{view}]: image file {refs[view]!r} is outside the benchmark "
        "directory; it is never read"
        for view in ("back", "left", "right", "top")
    ]
