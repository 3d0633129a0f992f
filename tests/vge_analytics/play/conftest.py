"""Fixtures of the `vge_analytics.play` tests (the hand-worked benchmark of the parent
conftest)."""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture
def bench(hand) -> Path:
    return hand["bench"]
