"""Errors the analytics raise on purpose, all `replay.VGEError` subclasses.

The CLI prints any of them as a one-line message (exit 1); the Python API lets them propagate.
"""

from __future__ import annotations

from replay import ConfigError, VGEError


class AnalyticsError(VGEError):
    """Base class of the analytics errors."""


class OutputDirError(AnalyticsError):
    """OUT is not a readable replay output directory (PROTOCOL §7)."""


class UnknownMetricError(ConfigError, AnalyticsError):
    """A metric name that is not in the registry."""


class MetricFileError(ConfigError, AnalyticsError):
    """A metrics folder (`--metrics-dir`) that cannot be used: every problem of every file,
    each on one line naming the file and the line (`path:line: what is wrong`)."""

    def __init__(self, problems: list[str], folder: str | None = None) -> None:
        self.problems = list(problems)
        """One line per problem, `path:line: message` (or `path: message` for the folder)."""
        if len(self.problems) == 1:
            message = self.problems[0]
        else:
            where = f" of {folder}" if folder else ""
            lines = "\n".join(f"  {p}" for p in self.problems)
            message = f"{len(self.problems)} problems in the metric files{where}:\n{lines}"
        super().__init__(message)


class UnknownColumnError(ConfigError, AnalyticsError):
    """A grouping or filter column that is not a (usable) column of the tables."""


class UnknownRunError(ConfigError, AnalyticsError):
    """A run id that is not in OUT."""


class QueryRefused(AnalyticsError):
    """`vge sql` refused a statement (writing, or reaching outside OUT)."""


class QueryError(AnalyticsError):
    """A read-only query failed (syntax, unknown column, ...)."""


class QueryLimitError(QueryError):
    """A query went past its memory or time limit and was stopped (`vge_analytics._limits`)."""

    def __init__(self, message: str, *, limit: str) -> None:
        self.limit = limit
        """Which limit: `time`, `memory` or `result`."""
        super().__init__(message)


class SweepRefused(AnalyticsError):
    """A lambda sweep cannot be computed from the logs that exist."""


class SweepInputError(AnalyticsError):
    """The inputs recorded in OUT/manifest.json cannot be found or read."""


__all__ = [
    "AnalyticsError",
    "MetricFileError",
    "OutputDirError",
    "QueryError",
    "QueryLimitError",
    "QueryRefused",
    "SweepInputError",
    "SweepRefused",
    "UnknownColumnError",
    "UnknownMetricError",
    "UnknownRunError",
]
