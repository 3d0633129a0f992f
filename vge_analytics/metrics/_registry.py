"""The metric registry (PROTOCOL §6): every metric defined once, in `vge_analytics/sql/<name>.sql`.

Each file holds a header of `-- key: value` lines (name, direction, unit, aggregation level,
grain, version, definition, null rule) and two SQL aggregate expressions, the numerator and
the denominator, over the rows of one table (its *grain*: `episodes`, `steps` or `goals`).

Every metric has the same shape::

    value = scale * sum(numerator) / sum(denominator)     (null when the denominator is 0)

with `scale` 100 for percentages and 1 otherwise. Both expressions are additive (counts and
sums), so the same definition gives a metric per group (aggregate the group's rows), per
episode (aggregate one episode's rows: what the paired bootstrap of `compare` resamples) and
the pooled value of any set of episodes (add their per-episode terms). An episode-mean metric
is the special case numerator = sum of per-episode values, denominator = number of episodes.

Unknown names raise `UnknownMetricError`; nothing returns None silently.

This module holds the built-in metrics; the files of a user's metrics folder use the same
format (`_metric_file`) and join them in a `MetricSet` (`_metric_set`).
"""

from __future__ import annotations

from functools import cache
from importlib import resources

from .._errors import UnknownMetricError
from ._file import Direction, Grain, Level, Metric, Unit, parse_metric_file

METRIC_NAMES: tuple[str, ...] = (
    "SR",
    "SSR",
    "SPL",
    "State-F1",
    "EIR",
    "TIR",
    "VSPS",
    "GVPE",
    "EER",
    "PSR",
    "AvgDist",
    "AvgWDist",
)
"""The paper's metrics, in PROTOCOL §6 order (the order of the paper's tables): what a
computation gives when it is not told which metrics."""

MAIN_TABLE: tuple[str, ...] = METRIC_NAMES[:9]
"""The paper's Table 2 (main results): SR SSR SPL State-F1 EIR TIR VSPS GVPE EER."""

CONTINUATION_METRICS: tuple[str, ...] = ("RecoveryRate", "StepsToRecover")
"""Built-in metrics of continuation runs (PROTOCOL §6, §10.4), computed when named (`--metrics
continuation`, or by name): every other run gives them no value, so they stay out of the
default tables."""

BUILTIN_NAMES: tuple[str, ...] = METRIC_NAMES + CONTINUATION_METRICS
"""Every built-in metric, in registry order."""

_FILES = {
    "SR": "sr.sql",
    "SSR": "ssr.sql",
    "SPL": "spl.sql",
    "State-F1": "state_f1.sql",
    "EIR": "eir.sql",
    "TIR": "tir.sql",
    "VSPS": "vsps.sql",
    "GVPE": "gvpe.sql",
    "EER": "eer.sql",
    "PSR": "psr.sql",
    "AvgDist": "avg_dist.sql",
    "AvgWDist": "avg_wdist.sql",
    "RecoveryRate": "recovery_rate.sql",
    "StepsToRecover": "steps_to_recover.sql",
}


def _parse(name: str, filename: str, text: str) -> Metric:
    where = f"vge_analytics/sql/{filename}"
    metric, problems = parse_metric_file(text, where)
    if metric is None:
        raise ValueError("; ".join(map(str, problems)))
    if metric.name != name:
        raise ValueError(f"{where}: declares metric {metric.name!r}, expected {name!r}")
    return metric


@cache
def registry() -> dict[str, Metric]:
    """All built-in metrics by name, in PROTOCOL §6 order, then the continuation metrics
    (files are read once, on first use)."""
    out: dict[str, Metric] = {}
    base = resources.files("vge_analytics") / "sql"
    for name in BUILTIN_NAMES:
        filename = _FILES[name]
        out[name] = _parse(name, filename, (base / filename).read_text(encoding="utf-8"))
    return out


def get_metric(name: str) -> Metric:
    """The metric called `name` (exactly as PROTOCOL §6 writes it); unknown names are an error."""
    metrics = registry()
    if name in metrics:
        return metrics[name]
    folded = {k.casefold(): k for k in metrics}
    hint = folded.get(name.casefold())
    extra = f" (did you mean {hint}?)" if hint else ""
    raise UnknownMetricError(
        f"unknown metric {name!r}{extra}; known metrics: {', '.join(BUILTIN_NAMES)}"
    )


def resolve_metrics(names: str | list[str] | tuple[str, ...] | None) -> list[Metric]:
    """Metric objects for a list of names (or a comma-separated string); None means the
    paper's (`METRIC_NAMES`)."""
    if names is None:
        return [registry()[n] for n in METRIC_NAMES]
    if isinstance(names, str):
        names = [n.strip() for n in names.split(",") if n.strip()]
    if not names:
        raise UnknownMetricError("no metric named; known metrics: " + ", ".join(BUILTIN_NAMES))
    seen: dict[str, Metric] = {}
    for n in names:
        m = get_metric(n)
        seen.setdefault(m.name, m)
    return list(seen.values())


__all__ = [
    "BUILTIN_NAMES",
    "CONTINUATION_METRICS",
    "MAIN_TABLE",
    "METRIC_NAMES",
    "Direction",
    "Grain",
    "Level",
    "Metric",
    "Unit",
    "get_metric",
    "registry",
    "resolve_metrics",
]
