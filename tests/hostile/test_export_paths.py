"""Exports write inside their destination only (issue 25, "Exports write outside their
destination"; docs/EXPORT.md, "Links in the destination"): a symbolic link where the export
writes a file is replaced by the file, its target left as it was; a symbolic link where it
writes a folder stops the export with one line naming it, nothing written through it.

The OUT: the hand-worked runs (tests/vge_analytics/conftest.py), whose views have pictures.
"""

from __future__ import annotations

import os
import zipfile
from pathlib import Path

import pytest

import replay
from tests.vge_analytics.conftest import _build_hand
from vge_analytics.cli import main
from vge_analytics.export import export

RUN = "kettle-vlm"
PRECIOUS = b"not the export's to write\n"


@pytest.fixture(scope="module")
def out(tmp_path_factory) -> Path:
    return _build_hand(tmp_path_factory.mktemp("hand"))["out"]


@pytest.fixture(autouse=True)
def cache(tmp_path, monkeypatch) -> None:
    monkeypatch.setenv("VGE_CACHE_DIR", str(tmp_path / "cache"))  # not the user's cache


def _victim(tmp_path: Path) -> Path:
    victim = tmp_path / "elsewhere" / "victim"
    victim.parent.mkdir()
    victim.write_bytes(PRECIOUS)
    return victim


def test_inspect_replaces_a_link_at_its_log_and_leaves_the_target(out, tmp_path) -> None:
    victim = _victim(tmp_path)
    dest = tmp_path / "dest"
    dest.mkdir()
    log = dest / f"{replay.io.safe_file_name(RUN)}.eval"
    log.symlink_to(victim)
    export(out, "inspect", dest, runs=[RUN], images="none")
    assert victim.read_bytes() == PRECIOUS  # the target is untouched
    assert not log.is_symlink() and zipfile.is_zipfile(log)  # the link became the log
    assert sorted(p.name for p in dest.iterdir()) == [log.name]  # no staging folder left


def test_atif_refuses_a_linked_images_folder_in_one_line(capsys, out, tmp_path) -> None:
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    dest = tmp_path / "dest"
    (dest / RUN).mkdir(parents=True)
    (dest / RUN / "images").symlink_to(elsewhere, target_is_directory=True)
    code = main(["export", str(out), "--format", "atif", "--out", str(dest), "--runs", RUN])
    assert code == 1
    err = capsys.readouterr().err
    assert err == (
        f"error: {dest / RUN / 'images'}: a symbolic link where a folder is written; nothing "
        "is written through a link: remove it, or write elsewhere\n"
    )
    assert list(elsewhere.iterdir()) == []  # not one picture went through the link


def test_atif_refuses_a_linked_run_folder(out, tmp_path) -> None:
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    dest = tmp_path / "dest"
    dest.mkdir()
    (dest / RUN).symlink_to(elsewhere, target_is_directory=True)
    with pytest.raises(replay.ConfigError, match="a symbolic link where a folder is written"):
        export(out, "atif", dest, runs=[RUN], images="none")
    assert list(elsewhere.iterdir()) == []


def test_atif_replaces_links_at_its_files(out, tmp_path) -> None:
    victim = _victim(tmp_path)
    clean = tmp_path / "clean"
    export(out, "atif", clean, runs=[RUN], images="embed")
    names = sorted(p.relative_to(clean) for p in clean.rglob("*") if p.is_file())
    pictures = [n for n in names if n.parts[1] == "images"]
    assert pictures, "the hand runs' views have pictures"
    # The same export into a destination where each file it writes is a link to the victim.
    dest = tmp_path / "dest"
    for name in names:
        (dest / name).parent.mkdir(parents=True, exist_ok=True)
        (dest / name).symlink_to(victim)
    export(out, "atif", dest, runs=[RUN], images="embed")
    assert victim.read_bytes() == PRECIOUS
    for name in names:
        path = dest / name
        assert not path.is_symlink(), name
        assert path.read_bytes() == (clean / name).read_bytes(), name
    assert not any(p.name.endswith(".tmp") for p in dest.rglob("*"))
    assert os.listdir(victim.parent) == ["victim"]
