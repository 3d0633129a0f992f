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


class EmptySelectionError(AnalyticsError):
    """Filters (`--where`, a dashboard facet) that select no row: almost always a typo. The
    message names the values no row holds and the nearest ones OUT does hold."""


class CommonEpisodesError(AnalyticsError):
    """Two runs cannot be compared episode by episode (`vge diff`): they share no episode,
    or an episode asked for is not replayed in both."""


class DifferentBenchmarksError(AnalyticsError):
    """Runs a comparison would pair were replayed against different benchmarks (their
    manifest entries' task or SSM digests differ): their episodes share ids, not tasks."""


class QueryRefused(AnalyticsError):
    """`vge sql` refused a statement (writing, or reaching outside OUT)."""


class QueryError(AnalyticsError):
    """A read-only query failed (syntax, unknown column, ...)."""


class QueryLimitError(QueryError):
    """A query went past its memory or time limit and was stopped (`vge_analytics.store._limits`)."""

    def __init__(self, message: str, *, limit: str) -> None:
        self.limit = limit
        """Which limit: `time`, `memory` or `result`."""
        super().__init__(message)


class AgentError(ConfigError, AnalyticsError):
    """The agent of `vge run` cannot be loaded or misbehaves (a module callable that raises or
    returns something other than text, an unknown profile, a service refusing the key)."""


class InfrastructureError(AnalyticsError):
    """A model request still failed after its retries. `vge run` records the episode as an
    infrastructure failure, apart from the agent's errors, and never scores it."""


class ServerUnreachableError(AgentError):
    """`vge run` cannot reach the model server when it checks it before the first episode
    (nothing listening, an unknown host, a timeout): nothing is played or written."""


class RequestRefusedError(AgentError):
    """The model server refused a request for good: a 4xx other than 408, 409 and 429 that
    is not a context-length refusal (a refused key, an unknown model, a parameter it does not
    take). Every request would be refused alike, so the run stops; the episodes written stay
    and `--resume` continues."""

    def __init__(self, message: str, *, status: int) -> None:
        self.status = status
        """The HTTP status of the refusal."""
        super().__init__(message)


class ContextExceededError(AnalyticsError):
    """The model refused a request as longer than its context window. Not a failure of the
    run: `vge run` ends the episode there, with the termination `context_exceeded`
    (PROTOCOL §3.5), an outcome of the agent's settings."""


class RunStoppedError(AnalyticsError):
    """`vge run` stopped before the end of its selection after too many consecutive
    infrastructure failures (exit 2): the episodes written stay, `--resume` continues."""


class RunDirError(AnalyticsError):
    """RUN_DIR of `vge run` cannot be started or resumed as asked."""


class PlayError(AnalyticsError):
    """A human run cannot be written as asked (`vge play`, the Play page)."""


class PlayConflictError(PlayError):
    """Another window changed the episode being played (played on, ended or discarded it)."""


class SweepRefused(AnalyticsError):
    """A lambda sweep cannot be computed from the logs that exist."""


class SweepInputError(AnalyticsError):
    """The inputs recorded in OUT/manifest.json cannot be found or read."""


__all__ = [
    "AgentError",
    "AnalyticsError",
    "CommonEpisodesError",
    "ContextExceededError",
    "DifferentBenchmarksError",
    "EmptySelectionError",
    "InfrastructureError",
    "MetricFileError",
    "OutputDirError",
    "PlayConflictError",
    "PlayError",
    "QueryError",
    "QueryLimitError",
    "QueryRefused",
    "RequestRefusedError",
    "RunDirError",
    "RunStoppedError",
    "ServerUnreachableError",
    "SweepInputError",
    "SweepRefused",
    "UnknownColumnError",
    "UnknownMetricError",
    "UnknownRunError",
]
