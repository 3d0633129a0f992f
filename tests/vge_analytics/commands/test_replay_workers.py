"""When `vge replay` starts its worker processes before anything else: when every run given
is to be replayed (a fresh local OUT, or `--force`); not where the runs may all be up to
date (the runner then starts workers only if it has runs to replay), nor with `--ray`."""

from __future__ import annotations

from pathlib import Path

import pytest

import replay
from vge_analytics.commands.replay import started_workers

LOGS = Path(__file__).parents[3] / "logs"


@pytest.mark.parametrize(
    ("replayed_before", "force", "ray", "started"),
    [
        (False, False, None, True),
        (True, False, None, False),
        (True, True, None, True),
        (False, False, "auto", False),
    ],
)
def test_workers_start_first_only_when_every_run_is_to_be_replayed(
    tmp_path: Path, replayed_before: bool, force: bool, ray: str | None, started: bool
) -> None:
    out = tmp_path / "out"
    if replayed_before:
        out.mkdir()
        replay.io.manifest_path(out).write_text("{}")
    with started_workers(2, ray, str(LOGS / "bench"), str(out), force) as executor:
        assert (executor is not None) == started
        assert executor is None or executor.slots == 2
