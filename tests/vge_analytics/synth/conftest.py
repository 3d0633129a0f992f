"""Shared fixtures for the synthetic-benchmark tests: one `tiny` generation per session."""

from __future__ import annotations

from pathlib import Path

import pytest

from vge_analytics.synth import generate


@pytest.fixture(scope="session")
def synth_tiny(tmp_path_factory) -> Path:
    """`vge synth --scale tiny --seed 0` output (read-only)."""
    out = tmp_path_factory.mktemp("synth-tiny")
    generate(out, scale="tiny", seed=0, workers=1)
    return out
