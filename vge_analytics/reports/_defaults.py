"""The defaults of the reports, in a module that imports nothing: the commands show them in
their help (`vge compare --help`), which must not wait for DuckDB or polars."""

from __future__ import annotations

DEFAULT_RESAMPLES = 2000
"""Bootstrap resamples of a comparison."""
DEFAULT_SEED = 0
"""Seed of a comparison's bootstrap."""
DEFAULT_RESCORE_BY: tuple[str, ...] = ("run_id",)
"""The groups a rescoring ranks."""
DEFAULT_SWEEP_METRICS: tuple[str, ...] = ("SR", "SSR")
"""The metrics of a budget sweep."""

__all__ = ["DEFAULT_RESAMPLES", "DEFAULT_RESCORE_BY", "DEFAULT_SEED", "DEFAULT_SWEEP_METRICS"]
