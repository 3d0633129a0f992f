"""The store's tests count small OUTs with polars too: below `POLARS_FROM_BYTES` of steps
files DuckDB's query counts them (quicker there), so the polars path would go untested; the
test that checks the threshold itself sets it back."""

from __future__ import annotations

import pytest

from vge_analytics.store import _scan_counts

POLARS_FROM_BYTES = _scan_counts.POLARS_FROM_BYTES
"""The module's own threshold, before the fixture below sets it to 0."""


@pytest.fixture(autouse=True)
def _polars_counts_small_outs(monkeypatch):
    monkeypatch.setattr(_scan_counts, "POLARS_FROM_BYTES", 0)
