"""OUT under a full disk and a late error (PROTOCOL §7.1): a run's partitions, the runs table
and the manifest change together or not at all, and the one-line error names the output
file that could not be written, never the input.

The full disk is a file-size limit (`RLIMIT_FSIZE`, no root needed): past it a write fails
with `EFBIG`, as it fails with `ENOSPC` on a full disk, through the same code."""

from __future__ import annotations

import resource
import signal
import subprocess
import sys
from pathlib import Path

import replay

from .replay_inputs import episode, line_ssm, task, write_bench, write_run

VGE = [sys.executable, "-m", "vge_analytics.cli"]
DEVICES = 300
"""A run over 300 devices: its manifest entry (an SSM reference each) is about 50 KB, its
Parquet parts about 15 KB each."""


def _limited(limit: int):
    def start() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a failed write, not a killed process
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    return start


def vge_replay(*args: object, limit: int | None = None) -> subprocess.CompletedProcess[str]:
    """`vge replay ARGS` as a real process, under a file-size limit if given."""
    return subprocess.run(
        [*VGE, "replay", *map(str, args)],
        preexec_fn=None if limit is None else _limited(limit),
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )


def one_press_run(tmp_path: Path) -> tuple[Path, Path]:
    """A benchmark of the device `press` with task e0, and a run of e0 (run id `r`)."""
    bench = write_bench(tmp_path / "bench", {"press": line_ssm(2)}, [task("e0", "press", "S1")])
    return bench, write_run(tmp_path / "run", [episode("e0")], run_id="r")


def snapshot(out: Path) -> dict[str, bytes]:
    return {str(p.relative_to(out)): p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()}


def test_a_disk_full_at_the_manifest_changes_nothing_and_names_it(tmp_path) -> None:
    devices = {f"d{i}": line_ssm(2) for i in range(DEVICES)}
    tasks = [task(f"e{i}", f"d{i}", "S1") for i in range(DEVICES)]
    bench = write_bench(tmp_path / "bench", devices, tasks)
    small = write_run(tmp_path / "a", [episode("e0")], run_id="a")
    wide = write_run(tmp_path / "b", [episode(f"e{i}") for i in range(DEVICES)], run_id="b")
    out = tmp_path / "out"
    assert vge_replay(small, "--bench", bench, "--out", out).returncode == 0
    before = snapshot(out)

    done = vge_replay(small, wide, "--bench", bench, "--out", out, limit=30_000)
    assert done.returncode == 1
    assert done.stderr.strip().splitlines() == [
        f"error: {out / 'manifest.json'}: cannot write: File too large"
    ]
    assert snapshot(out) == before  # no partition of b, no runs row, no temporary file
    manifest = replay.read_manifest(out)
    assert manifest is not None and [r.run_id for r in manifest.runs] == ["a"]

    again = vge_replay(small, wide, "--bench", bench, "--out", out)
    assert again.returncode == 0  # the next replay, with room, completes it
    assert [r.run_id for r in replay.read_manifest(out).runs] == ["a", "b"]


def test_a_disk_full_in_a_part_names_the_part(tmp_path) -> None:
    bench, run = one_press_run(tmp_path)
    out = tmp_path / "out"
    done = vge_replay(run, "--bench", bench, "--out", out, limit=2_000)
    assert done.returncode == 1
    (line,) = done.stderr.strip().splitlines()
    assert line.startswith(f"error: {out / '.replay' / 'staging' / 'r'}/")
    assert line.endswith(".parquet: cannot write: File too large")
    assert str(run) not in line
    assert not (out / "manifest.json").exists()


def test_a_second_writer_into_one_out_is_refused_in_one_line(tmp_path) -> None:
    """The lock a running `vge replay` holds (taken here by this process) refuses a second
    one before it writes anything."""
    bench, run = one_press_run(tmp_path)
    out = tmp_path / "out"
    with replay.io._outdir.OutputLock(replay.io._fs.location(out)):
        done = vge_replay(run, "--bench", bench, "--out", out)
    assert done.returncode == 1
    assert done.stderr.strip().splitlines() == [
        f"error: {out}: another vge replay is writing to this directory"
    ]
    assert sorted(p.name for p in out.rglob("*")) == [".replay", "lock"]


def test_a_link_in_place_of_the_lock_is_never_followed(tmp_path) -> None:
    bench, run = one_press_run(tmp_path)
    target = tmp_path / "precious.txt"
    target.write_text("keep me")
    out = tmp_path / "out"
    (out / ".replay").mkdir(parents=True)
    (out / ".replay" / "lock").symlink_to(target)
    done = vge_replay(run, "--bench", bench, "--out", out)
    assert done.returncode == 1
    assert done.stderr.strip().splitlines() == [
        f"error: {out / '.replay' / 'lock'}: cannot take the writer lock: Too many levels of "
        "symbolic links"
    ]
    assert target.read_text() == "keep me"


def test_writers_of_runs_and_schemas_never_follow_a_link(tmp_path) -> None:
    """`RunDirectory.stream` (what `vge synth` writes its runs through) and `write_schemas`
    replace a link left at their file; its target keeps its bytes."""
    target = tmp_path / "precious.txt"
    target.write_text("keep me")
    run = replay.io.RunDirectory(tmp_path / "run")
    (tmp_path / "run").mkdir()
    for name, compress in (("episodes.jsonl", False), ("episodes.jsonl.gz", True)):
        (tmp_path / "run" / name).symlink_to(target)
        with run.stream(compress=compress) as fh:
            fh.write(episode("e0") + b"\n")
        assert not (tmp_path / "run" / name).is_symlink()
    schemas = tmp_path / "schemas"
    schemas.mkdir()
    (schemas / "manifest.schema.json").symlink_to(target)
    written = replay.io.write_schemas(schemas)
    assert schemas / "manifest.schema.json" in written
    assert not (schemas / "manifest.schema.json").is_symlink()
    assert target.read_text() == "keep me"
