"""The metrics (PROTOCOL §6): each defined once, in its `.sql` file, in one registry, with the
metric files users add, their checks, the computation in DuckDB and the polars cross-check."""

from typing import TYPE_CHECKING

from replay import lazy_names

if TYPE_CHECKING:  # the names, imported when first used (`lazy_names`)
    from ._compute import (
        episode_terms,
        metric_table,
        metrics,
    )
    from ._polars import (
        polars_metrics,
    )
    from ._registry import (
        BUILTIN_NAMES,
        CONTINUATION_METRICS,
        MAIN_TABLE,
        METRIC_NAMES,
        Metric,
        get_metric,
        registry,
    )
    from ._set import (
        METRIC_GROUPS,
        METRICS_DIR_ENV,
        MetricSet,
        MetricsSource,
        default_folder,
        fingerprint,
        folder_fingerprint,
        load_metrics,
        metric_set,
        same_definition,
    )

__all__ = [
    "BUILTIN_NAMES",
    "CONTINUATION_METRICS",
    "default_folder",
    "episode_terms",
    "fingerprint",
    "folder_fingerprint",
    "get_metric",
    "load_metrics",
    "MAIN_TABLE",
    "Metric",
    "METRIC_GROUPS",
    "METRIC_NAMES",
    "metric_set",
    "metric_table",
    "metrics",
    "METRICS_DIR_ENV",
    "MetricSet",
    "MetricsSource",
    "polars_metrics",
    "registry",
    "same_definition",
]

__getattr__, __dir__ = lazy_names(__name__, __file__)
