"""`confinement`: many paths checked against one root give `os.path.realpath`'s verdict."""

from __future__ import annotations

import os
from pathlib import Path

from replay.io._fs import confined, confinement, location


def _verdict(root: Path, path: Path) -> bool:
    """What `confined` answered before it resolved parents once: both paths in full."""
    return os.path.realpath(path).startswith(os.path.join(os.path.realpath(root), ""))


def test_links_in_and_out_of_the_root(tmp_path: Path) -> None:
    root, outside = tmp_path / "bench", tmp_path / "elsewhere"
    (root / "ssm").mkdir(parents=True)
    outside.mkdir()
    (outside / "x.json").write_text("{}")
    (root / "ssm" / "plain.json").write_text("{}")
    (root / "ssm" / "out.json").symlink_to(outside / "x.json")
    (root / "ssm" / "in.json").symlink_to(root / "ssm" / "plain.json")
    (root / "linked").symlink_to(outside)  # a directory linked out: all under it is outside
    (root / "ssm" / "dangling.json").symlink_to(tmp_path / "nothing.json")
    names = {
        root / "ssm" / "plain.json": True,
        root / "ssm" / "missing.json": True,  # not there yet: where it would be
        root / "ssm" / "in.json": True,
        root / "ssm" / "out.json": False,
        root / "linked" / "x.json": False,
        root / "ssm" / "dangling.json": False,
        root / "ssm" / "..": False,  # the root itself is not inside it
        root / "ssm" / ".." / "ssm" / "plain.json": True,
        tmp_path / "bench-other" / "x.json": False,  # a sibling sharing the prefix
    }
    inside = confinement(location(root))
    for path, expected in names.items():
        assert inside(location(path)) is expected, path
        assert confined(location(root), location(path)) is expected, path
        assert _verdict(root, path) is expected, path


def test_a_relative_root_and_paths(tmp_path: Path, monkeypatch) -> None:
    (tmp_path / "bench" / "ssm").mkdir(parents=True)
    (tmp_path / "bench" / "ssm" / "up.json").symlink_to(tmp_path / "up.json")
    monkeypatch.chdir(tmp_path)
    inside = confinement(location("bench"))
    assert inside(location("bench/ssm/a.json"))
    assert not inside(location("bench/ssm/up.json"))
    assert not inside(location("other/a.json"))
