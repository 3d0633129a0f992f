"""`_datasets._real`, the path check's resolution of a file's path from its folder's, gives
`os.path.realpath`'s answer whichever part of the path is a link."""

from __future__ import annotations

import os
from pathlib import Path

from vge_analytics.store._contents import _real


def test_resolved_as_realpath_resolves(tmp_path: Path):
    run_a = tmp_path / "out" / "steps" / "run_id=a"
    elsewhere = tmp_path / "elsewhere" / "x"
    run_a.mkdir(parents=True)
    elsewhere.mkdir(parents=True)
    (run_a / "p.parquet").touch()
    (elsewhere / "p.parquet").touch()
    (run_a.parent / "run_id=b").symlink_to(elsewhere)  # a folder that is a link
    (run_a / "q.parquet").symlink_to(elsewhere / "p.parquet")  # a file that is a link
    (run_a.parent / "rel").symlink_to("../../elsewhere")  # a relative link
    folders: dict[str, str] = {}
    names = [
        "out/steps/run_id=a/p.parquet",
        "out/steps/run_id=b/p.parquet",
        "out/steps/run_id=a/q.parquet",
        "out/steps/rel/x/p.parquet",
        "out/steps/./run_id=a/p.parquet",
        "out/steps/run_id=a/missing.parquet",
    ]
    for name in names:
        path = os.path.join(tmp_path, name)
        assert os.path.normpath(_real(path, folders)) == os.path.realpath(path), name
    assert os.path.realpath(tmp_path / "out/steps/run_id=b/p.parquet").startswith(
        str(elsewhere.resolve())
    )
