"""Fixtures of the export tests: the hand-worked runs (`hand_out`, tests/vge_analytics/conftest.py)
exported once per session in each format, with their pictures; the same runs with the usage
a harness records (`out_with_usage`); from the dashboard's tests,
the temporary cache for the rendered views (not the user's) and Chromium's launch options."""

from __future__ import annotations

import shutil
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
import pytest

import vge_analytics as va
from tests.app.conftest import (  # noqa: F401 (fixtures)
    browser_context_args,
    browser_type_launch_args,
    cache_dir,
)
from vge_analytics.export import ExportSummary, export


@pytest.fixture(scope="session")
def hand_inspect(hand_out, tmp_path_factory) -> tuple[Path, ExportSummary]:
    """The hand-worked runs as Inspect logs, pictures embedded."""
    dest = tmp_path_factory.mktemp("inspect")
    return dest, export(hand_out, "inspect", dest, images="embed")


@pytest.fixture(scope="session")
def hand_atif(hand_out, tmp_path_factory) -> tuple[Path, ExportSummary]:
    """The hand-worked runs as ATIF trajectories, pictures written beside them."""
    dest = tmp_path_factory.mktemp("atif")
    return dest, export(hand_out, "atif", dest, images="embed")


USAGE = {"prompt_tokens": 1000, "completion_tokens": 50, "latency_s": 1.25, "cost_usd": 0.002}


@pytest.fixture(scope="module")
def out_with_usage(hand_out, tmp_path_factory) -> Path:
    """hand_out with the steps table's usage columns filled, as the replay of a harness that
    records them fills them: a value on the kettle run's scored steps, null on its truncated
    ones and on the oven run (a human run has no model call)."""
    out = tmp_path_factory.mktemp("usage") / "out"
    shutil.copytree(hand_out, out)
    for part in (out / "steps").rglob("*.parquet"):
        table = pq.read_table(part)
        kettle = [r == "kettle-vlm" for r in table["run_id"].to_pylist()]
        truncated = table["truncated"].to_pylist()
        for name, value in USAGE.items():
            kind = pa.int64() if isinstance(value, int) else pa.float64()
            values = [
                value if k and not t else None for k, t in zip(kettle, truncated, strict=True)
            ]
            at = table.schema.get_field_index(name)
            table = table.set_column(at, name, pa.array(values, kind))
        pq.write_table(table, part)
    va.clear_cache()
    return out
