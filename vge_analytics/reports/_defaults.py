"""The defaults of the reports, in a module that imports nothing: the commands show them in
their help (`vge compare --help`), which must not wait for DuckDB or polars."""

from __future__ import annotations

DEFAULT_RESAMPLES = 2000
"""Bootstrap resamples of a comparison."""
DEFAULT_SEED = 0
"""Seed of a comparison's bootstrap."""
CLUSTER_UNITS: tuple[str, ...] = ("device", "category", "episode")
"""What a cluster is: a device (its episodes move together), a category (its devices do),
or an episode (no clustering: every episode its own cluster)."""
DEFAULT_CLUSTER = "device"
"""The unit a comparison resamples (docs/STATISTICS.md)."""
CORRECTIONS: tuple[str, ...] = ("holm", "bh", "none")
"""Corrections of a family of p-values: Holm's step-down, Benjamini-Hochberg, none."""
DEFAULT_CORRECTION = "holm"
DEFAULT_ALPHA = 0.05
"""The level at which runs count as tied (`vge compare --all`)."""
DEFAULT_DELTA = 5.0
"""The difference in points a study should detect (`vge power`)."""
DEFAULT_POWER = 0.8
DEFAULT_RESCORE_BY: tuple[str, ...] = ("run_id",)
"""The groups a rescoring ranks."""
DEFAULT_SWEEP_METRICS: tuple[str, ...] = ("SR", "SSR")
"""The metrics of a budget sweep."""

__all__ = [
    "CLUSTER_UNITS",
    "CORRECTIONS",
    "DEFAULT_ALPHA",
    "DEFAULT_CLUSTER",
    "DEFAULT_CORRECTION",
    "DEFAULT_DELTA",
    "DEFAULT_POWER",
    "DEFAULT_RESAMPLES",
    "DEFAULT_RESCORE_BY",
    "DEFAULT_SEED",
    "DEFAULT_SWEEP_METRICS",
]
