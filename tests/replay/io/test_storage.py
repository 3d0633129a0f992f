"""Inputs and outputs named by URIs (`replay.io._fs`, docs/SCALE.md): `file://` URIs, a
filesystem without renames (the object-store commit protocol, run on the local disk), and a
real S3-compatible server (moto, over HTTP on 127.0.0.1) read and written by pyarrow's
S3FileSystem. Whatever the storage, the files are byte-identical to a plain local replay,
incremental skipping and `force` behave the same, and an interrupted replay leaves what a
reader trusts (the runs the manifest lists) complete."""

from __future__ import annotations

import hashlib
import re
from pathlib import Path
from urllib.parse import unquote, urlsplit

import pyarrow.fs as pafs
import pytest

import replay
import vge_analytics as va
from replay.io import _batch, _files, _fs

from ..conftest import Sample
from .conftest import fail_after


def _digests(out: Path) -> dict[str, str]:
    """sha256 of every file but the private state."""
    return {
        p.relative_to(out).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(out.rglob("*"))
        if p.is_file() and ".replay" not in p.relative_to(out).parts
    }


def _inodes(out: Path) -> dict[str, int]:
    return {k: (out / k).stat().st_ino for k in _digests(out)}


def _replay(runs, bench, out, **options) -> replay.Manifest:
    return replay.replay_runs(
        runs,
        bench,
        out,
        mcap=True,
        image_source=replay.BenchImages(str(bench)),
        progress=False,
        **options,
    )


@pytest.fixture
def small_batches(monkeypatch: pytest.MonkeyPatch) -> None:
    """Many parts per run, so that commits move and delete several files."""
    monkeypatch.setattr("replay.io._job.BATCH_LINES", 4)


# --------------------------------------------------------------------------- file://


def test_file_uris_write_the_same_files(sample: Sample, tmp_path: Path) -> None:
    local = tmp_path / "local"
    _replay(sample.runs, sample.bench, local)
    # OUT as a URI: every file identical, the manifest's path on the local disk
    m = _replay(sample.runs, sample.bench, f"file://{tmp_path / 'uri-out'}")
    assert _digests(tmp_path / "uri-out") == _digests(local)
    assert m.path == tmp_path / "uri-out" / "manifest.json"
    # inputs as URIs too: the same tables and MCAP files (images read through the URI);
    # the manifest and the quarantine name the inputs as given
    runs = [f"file://{p}" for p in sample.runs]
    m = _replay(runs, f"file://{sample.bench}", f"file://{tmp_path / 'uris'}")
    assert m.run("vlm-a").inputs.episodes.path == f"file://{sample.vlm}/episodes.jsonl"
    got, want = _digests(tmp_path / "uris"), _digests(local)
    assert got.keys() == want.keys()
    for name in ("manifest.json", "quarantine.jsonl"):
        text = (tmp_path / "uris" / name).read_bytes().replace(b"file://", b"")
        assert text == (local / name).read_bytes(), name
        del got[name], want[name]
    assert got == want
    assert any(k.endswith(".mcap") for k in got)


def test_a_bad_uri_is_one_line(sample: Sample, tmp_path: Path) -> None:
    with pytest.raises(replay.InputError, match=r"^nosuch://x/out: cannot open: .*nosuch"):
        replay.replay_runs(sample.runs, sample.bench, "nosuch://x/out", progress=False)
    with pytest.raises(replay.InputError, match="run directory not found"):
        replay.replay_runs([f"file://{tmp_path}/none"], sample.bench, tmp_path, progress=False)


def test_locations_print_as_given_and_round_trip() -> None:
    root = replay.location("file:///tmp/a%20b/out?x=1")
    child = root / "mcap" / "run" / "id %2F#odd.mcap"
    assert str(child) == "file:///tmp/a%20b/out/mcap/run/id%20%252F%23odd.mcap?x=1"
    assert child.local == Path("/tmp/a b/out/mcap/run/id %2F#odd.mcap")
    again = replay.location(str(child))  # how a worker reopens it
    assert again.local == child.local and again == child
    plain = replay.location("rel/dir") / "run.json"
    assert str(plain) == "rel/dir/run.json" and plain.local == Path("rel/dir/run.json")


# ----------------------------------------------------- the object-store protocol, on disk


@pytest.fixture
def no_rename(monkeypatch: pytest.MonkeyPatch):
    """`norename:///abs/path`: the local disk through pyarrow's SubTreeFileSystem, which the
    writer treats like an object store (no rename, no lock, files moved by copy and
    delete). Returns a function naming a local path that way."""
    fs = pafs.SubTreeFileSystem("/", pafs.LocalFileSystem())
    monkeypatch.setattr(_fs, "_OPENED", {})
    monkeypatch.setitem(_fs._FACTORIES, "norename", lambda uri: (fs, unquote(urlsplit(uri).path)))
    return lambda path: f"norename://{path}"


def test_object_store_protocol_writes_the_same_files(
    no_rename, small_batches, copy_sample: Sample, tmp_path: Path
) -> None:
    s = copy_sample
    local, out = tmp_path / "local", tmp_path / "remote"
    _replay(s.runs, s.bench, local)
    first = _replay(s.runs, s.bench, no_rename(out))
    assert _digests(out) == _digests(local)
    assert first.path == f"norename://{out}/manifest.json"
    assert not (out / ".replay" / "lock").exists()  # no lock where nothing can hold one
    assert not (out / ".replay" / "staging").exists()
    # up to date: skipped, nothing rewritten
    before = _inodes(out)
    again = _replay(s.runs, s.bench, no_rename(out))
    assert again.skipped == ["human-1", "vlm-a"] and again.replayed == []
    parts = [k for k in before if "run_id=" in k or k.startswith("mcap/")]
    assert parts and all(_inodes(out)[k] == before[k] for k in parts)
    # forced: replayed, the same bytes
    forced = _replay(s.runs, s.bench, no_rename(out), force=True)
    assert forced.replayed == ["human-1", "vlm-a"]
    assert _digests(out) == _digests(local)
    # a shorter log: fewer parts; the old version's extra parts and MCAP files are deleted
    lines = (s.vlm / "episodes.jsonl").read_bytes().splitlines(keepends=True)
    (s.vlm / "episodes.jsonl").write_bytes(b"".join(lines[:9]))
    shorter = _replay(s.runs, s.bench, no_rename(out))
    assert shorter.replayed == ["vlm-a"] and shorter.skipped == ["human-1"]
    _replay(s.runs, s.bench, local)
    assert _digests(out) == _digests(local)


def test_object_store_interrupted_mid_run_keeps_the_previous_output(
    no_rename, small_batches, copy_sample: Sample, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    s, out, local = copy_sample, tmp_path / "remote", tmp_path / "local"
    _replay(s.runs, s.bench, no_rename(out))
    before = _digests(out)
    with monkeypatch.context() as patch:
        fail_after(patch, _batch, "write_part", 5)
        with pytest.raises(replay.InputError, match="simulated crash"):
            _replay(s.runs, s.bench, no_rename(out), force=True)
    assert _digests(out) == before  # nothing a reader sees has changed
    assert not (out / ".replay" / "staging").exists()
    _replay(s.runs, s.bench, local)
    m = _replay(s.runs, s.bench, no_rename(out), force=True)
    assert m.replayed == ["human-1", "vlm-a"] and _digests(out) == _digests(local)


def test_object_store_interrupted_mid_commit_withdraws_the_run(
    no_rename, small_batches, copy_sample: Sample, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A commit replaces a run's files one by one; the run is out of the manifest meanwhile,
    so a reader trusting the manifest never sees it half replaced, and the next replay
    replays it again (the other runs stay as they were)."""
    s, out, local = copy_sample, tmp_path / "remote", tmp_path / "local"
    _replay(s.runs, s.bench, no_rename(out))
    with monkeypatch.context() as patch:
        fail_after(patch, _fs.Location, "replace", 3)
        with pytest.raises(OSError, match="simulated crash"):
            replay.replay_runs(s.runs, s.bench, no_rename(out), force=True, progress=False)
    listed = replay.read_manifest(no_rename(out))
    assert listed is not None and [r.run_id for r in listed.runs] == ["vlm-a"]
    for path in listed.runs[0].outputs.steps:  # what the manifest lists is there
        assert (out / path).is_file()
    again = _replay(s.runs, s.bench, no_rename(out))
    assert again.replayed == ["human-1"] and again.skipped == ["vlm-a"]
    _replay(s.runs, s.bench, local)
    assert _digests(out) == _digests(local)


def test_commit_dir_moves_files_in_and_deletes_the_rest(no_rename, tmp_path: Path) -> None:
    root = replay.location(no_rename(tmp_path))
    for rel, data in (("staged/a", b"new a"), ("staged/sub/b", b"new b")):
        (root / rel).write_bytes(data)
    for rel, data in (("final/a", b"old a"), ("final/stale", b"old")):
        (root / rel).write_bytes(data)
    _files.commit_dir(root / "staged", root / "final", root / "trash")
    assert (root / "final").files() == ["a", "sub/b"]
    assert (root / "final" / "a").read_bytes() == b"new a"
    assert not (root / "staged").exists() and not (root / "trash").exists()


# ------------------------------------------------- the writer lock of an object store


def test_object_store_second_writer_is_refused_in_one_line(
    no_rename, sample: Sample, tmp_path: Path
) -> None:
    """The lease a running `vge replay` holds (taken here by this process) refuses a second
    one before it writes anything; released, it leaves nothing in OUT."""
    out = tmp_path / "remote"
    uri = no_rename(out)
    with replay.io._outdir.OutputLock(replay.location(uri)):
        with pytest.raises(replay.ConfigError) as refused:
            _replay(sample.runs, sample.bench, uri)
        assert sorted(p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file()) == [
            ".replay/lock"
        ]
    line = str(refused.value)
    assert line.startswith(
        f"{uri}: another vge replay is writing to this directory (its lock {uri}/.replay/lock "
        f"is held by "
    )
    assert line.endswith(" s)") and "\n" not in line
    assert not (out / ".replay" / "lock").exists()
    assert _replay(sample.runs, sample.bench, uri).replayed == ["human-1", "vlm-a"]
    assert not (out / ".replay" / "lock").exists()


def test_object_store_writer_that_lost_its_lease_stops_before_its_commit(
    no_rename, small_batches, copy_sample: Sample, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Another writer overwrote the lease while this one replayed (two started at once): this
    one stops at its next check, before its commit; OUT is as it was."""
    s, out = copy_sample, tmp_path / "remote"
    _replay(s.runs, s.bench, no_rename(out))
    before = _digests(out)
    real = _batch.write_part

    def write_part(*args, **kwargs):
        (out / ".replay" / "lock").write_bytes(b"other-host pid 1 0123456789abcdef")
        return real(*args, **kwargs)

    monkeypatch.setattr(_batch, "write_part", write_part)
    with pytest.raises(replay.ConfigError, match=r"lost its lock .* \(taken by another writer\)"):
        _replay(s.runs, s.bench, no_rename(out), force=True)
    assert _digests(out) == before
    # the other writer's lease is left to it
    assert (out / ".replay" / "lock").read_bytes() == b"other-host pid 1 0123456789abcdef"


def test_object_store_lease_of_a_dead_writer_expires(
    no_rename, sample: Sample, tmp_path: Path
) -> None:
    import os

    from replay.io._lease import LEASE_SECONDS

    out = tmp_path / "remote"
    lock = out / ".replay" / "lock"
    lock.parent.mkdir(parents=True)
    lock.write_bytes(b"dead-host pid 2 fedcba9876543210")
    old = lock.stat().st_mtime - LEASE_SECONDS - 5
    os.utime(lock, (old, old))  # last renewed past the lease: its writer is gone
    assert _replay(sample.runs, sample.bench, no_rename(out)).replayed == ["human-1", "vlm-a"]
    assert not lock.exists()


def test_a_lease_is_renewed_and_notices_a_takeover(
    no_rename, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import time

    from replay.io import _lease

    monkeypatch.setattr(_lease, "RENEW_SECONDS", 0.05)
    path = replay.location(no_rename(tmp_path / ".replay" / "lock"))
    lease = _lease.Lease(path, "OUT")
    lease.take()
    local = tmp_path / ".replay" / "lock"
    first = local.stat().st_mtime_ns
    for _ in range(200):  # renewed: a later write time (bounded wait, no timing asserted)
        if local.stat().st_mtime_ns != first:
            break
        time.sleep(0.05)
    assert local.stat().st_mtime_ns != first
    lease.check()
    # Another writer takes over. A renewal that read our token just before this write can
    # still overwrite it (as with a real second writer, whose own check then stops it), so
    # the takeover is written again until the renewing thread has noticed it.
    for _ in range(200):
        if lease._lost is not None:
            break
        local.write_bytes(b"someone else")
        time.sleep(0.05)
    with pytest.raises(replay.ConfigError, match="taken by another writer"):
        lease.check()
    lease.release()
    assert local.read_bytes() == b"someone else"  # not ours: left in place


# ------------------------------------------------------------- S3 (moto over real HTTP)


def _download(fs: pafs.FileSystem, prefix: str, target: Path) -> None:
    pafs.copy_files(prefix, str(target), source_filesystem=fs)


def test_cli_replays_into_s3(
    s3_server, vge, sample: Sample, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    fs, query = s3_server
    out = f"s3://vge/out-cli?{query}"
    argv = ["replay", str(sample.human), "--bench", str(sample.bench), "--out", out]
    assert vge([*argv, "--no-progress"]) == 0
    assert f"wrote {out}" in capsys.readouterr().out.replace("\n", "")
    manifest = replay.read_manifest(out)
    assert manifest is not None and [r.run_id for r in manifest.runs] == ["human-1"]


def test_s3_output_is_byte_identical_and_incremental(
    s3_server, small_batches, sample: Sample, tmp_path: Path
) -> None:
    fs, query = s3_server
    local = tmp_path / "local"
    _replay(sample.runs, sample.bench, local)
    out = f"s3://vge/out-a?{query}"
    first = _replay(sample.runs, sample.bench, out, workers=2)
    assert first.path == f"s3://vge/out-a/manifest.json?{query}"
    _download(fs, "vge/out-a", tmp_path / "got")
    assert _digests(tmp_path / "got") == _digests(local)
    assert not [i for i in fs.get_file_info(pafs.FileSelector("vge/out-a/.replay/staging",
                                                               allow_not_found=True))]  # fmt: skip
    again = _replay(sample.runs, sample.bench, out)
    assert again.skipped == ["human-1", "vlm-a"] and again.content == first.content
    assert replay.read_manifest(out) == first.content


def test_s3_inputs(s3_server, sample: Sample, tmp_path: Path) -> None:
    """Run directories and the benchmark (SSMs, tasks, view images) read from the bucket."""
    fs, query = s3_server
    pafs.copy_files(str(sample.root), "vge/inputs", destination_filesystem=fs)
    local = tmp_path / "local"
    want = _replay(sample.runs, sample.bench, local)

    def uri(path: Path) -> str:
        return f"s3://vge/inputs/{path.relative_to(sample.root).as_posix()}?{query}"

    got = _replay([uri(p) for p in sample.runs], uri(sample.bench), f"s3://vge/out-b?{query}")
    _download(fs, "vge/out-b", tmp_path / "got")
    digests, expected = _digests(tmp_path / "got"), _digests(local)
    tables = [k for k in expected if k.endswith((".parquet", ".mcap"))]
    assert tables and all(digests[k] == expected[k] for k in tables)
    for a, b in zip(got.runs, want.runs, strict=True):  # the same inputs, named by URIs
        assert a.inputs.episodes.sha256 == b.inputs.episodes.sha256
        assert re.match(
            r"^s3://vge/inputs/runs/\w+/episodes\.jsonl(\.gz)?\?", a.inputs.episodes.path
        )
        assert a.counts == b.counts and a.outputs == b.outputs


def test_sweep_rereads_s3_inputs(s3_server, sample: Sample, tmp_path: Path) -> None:
    """`vge sweep` replays again from the inputs the manifest records: here URIs."""
    fs, query = s3_server
    pafs.copy_files(str(sample.root), "vge/sweep-inputs", destination_filesystem=fs)

    def uri(path: Path) -> str:
        return f"s3://vge/sweep-inputs/{path.relative_to(sample.root).as_posix()}?{query}"

    replay.replay_runs(sample.runs, sample.bench, tmp_path / "local", progress=False)
    replay.replay_runs(
        [uri(p) for p in sample.runs], uri(sample.bench), tmp_path / "uris", progress=False
    )
    want = va.sweep(tmp_path / "local", [2, 5], metrics=["SR", "SSR"])
    assert va.sweep(tmp_path / "uris", [2, 5], metrics=["SR", "SSR"]).equals(want)


def test_analytics_read_an_out_in_s3(
    s3_server, sample: Sample, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The metrics, the error taxonomy, the sweep and read-only SQL over OUT in the bucket:
    the same numbers as over the local copy; DuckDB still reads no file; a replay that adds
    a run is seen at the next query."""
    from vge_analytics.cli import main
    from vge_analytics.dashboard import check_out

    fs, query = s3_server
    local = tmp_path / "local"
    _replay(sample.runs, sample.bench, local)
    out = f"s3://vge/analytics?{query}"
    _replay([sample.human], sample.bench, out)
    assert va.metrics(out)["run_id"].to_list() == ["human-1"]
    _replay(sample.runs, sample.bench, out)  # a second run: the manifest changes
    assert va.metrics(out).equals(va.metrics(local))
    assert va.metrics(out).height == 2
    assert va.error_distribution(out, ["run_id"]).equals(va.error_distribution(local, ["run_id"]))
    assert va.switch_classes(out, ["run_id"]).equals(va.switch_classes(local, ["run_id"]))
    every = "SELECT * FROM {} ORDER BY ALL"
    for table in ("runs", "episodes", "goals", "steps"):
        assert va.sql(out, every.format(table)).equals(va.sql(local, every.format(table)))
    # The sweep replays again from the inputs the manifest records (local paths here).
    assert va.sweep(out, [2, 5]).equals(va.sweep(local, [2, 5]))
    # No file access for queries, whatever OUT is.
    with pytest.raises(va.QueryRefused, match="access outside"):
        va.sql(out, f"SELECT * FROM read_parquet('{local}/runs/*.parquet')")
    # The commands take the URI as it is.
    capsys.readouterr()
    assert main(["metrics", out, "-f", "json"]) == 0
    remote = capsys.readouterr().out
    assert main(["metrics", str(local), "-f", "json"]) == 0
    assert remote == capsys.readouterr().out
    assert main(["sql", out, "SELECT count(*) AS n FROM steps", "-f", "csv"]) == 0
    n = va.sql(local, "SELECT count(*) AS n FROM steps")["n"][0]
    assert capsys.readouterr().out == f"n\n{n}\n"
    # Only the files the manifest lists are read: a part not (yet) in it, as a run being
    # committed has, is not counted.
    part = "vge/analytics/steps/run_id=human-1/part-00000.parquet"
    fs.copy_file(part, part.replace("run_id=human-1", "run_id=ghost"))
    va.clear_cache()
    assert va.sql(out, "SELECT count(*) AS n FROM steps")["n"][0] == n
    # file:// is the local directory; the dashboard says where to read a remote OUT.
    assert va.metrics(f"file://{local}").equals(va.metrics(local))
    with pytest.raises(va.OutputDirError, match="the dashboard reads OUT on this machine"):
        check_out(out)
    missing = f"s3://vge/nothing-here?{query}"
    with pytest.raises(va.OutputDirError, match="not a replay output \\(no manifest.json\\)"):
        va.metrics(missing)
