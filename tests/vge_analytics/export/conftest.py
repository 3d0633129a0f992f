"""Fixtures of the export tests: the hand-worked runs (`hand_out`, tests/vge_analytics/conftest.py)
exported once per session in each format, with their pictures; from the dashboard's tests,
the temporary cache for the rendered views (not the user's) and Chromium's launch options."""

from __future__ import annotations

from pathlib import Path

import pytest

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
