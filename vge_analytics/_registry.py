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
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import cache
from importlib import resources
from typing import Literal

from ._errors import UnknownMetricError

Direction = Literal["higher", "lower"]
Unit = Literal["percent", "ratio", "distance"]
Level = Literal["episode-mean", "step-ratio", "run-level ratio", "goal-ratio"]
Grain = Literal["episodes", "steps", "goals"]

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
"""Every metric, in PROTOCOL §6 order (the order of the paper's tables)."""

MAIN_TABLE: tuple[str, ...] = METRIC_NAMES[:9]
"""The paper's Table 2 (main results): SR SSR SPL State-F1 EIR TIR VSPS GVPE EER."""

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
}

_SCALES = {"percent": 100.0, "ratio": 1.0, "distance": 1.0}
_HEADER = re.compile(r"^--\s*([a-z_]+):\s?(.*)$")
_CONTINUATION = re.compile(r"^--\s{2,}(.*)$")
_SECTION = re.compile(r"^--\s*(numerator|denominator)\s*$")


@dataclass(frozen=True, slots=True)
class Metric:
    """One registered metric; `numerator`/`denominator` are SQL aggregates over `grain` rows."""

    name: str
    title: str
    direction: Direction
    unit: Unit
    level: Level
    grain: Grain
    version: int
    definition: str
    null_rule: str
    numerator: str
    denominator: str
    source: str

    @property
    def scale(self) -> float:
        """100 for percentages, 1 for ratios and distances."""
        return _SCALES[self.unit]

    @property
    def higher_is_better(self) -> bool:
        return self.direction == "higher"

    @property
    def arrow(self) -> str:
        """The paper's header arrow: up when higher is better."""
        return "\u2191" if self.higher_is_better else "\u2193"


def _parse(name: str, filename: str, text: str) -> Metric:
    header: dict[str, str] = {}
    sections: dict[str, list[str]] = {}
    current_key: str | None = None
    current_section: str | None = None
    for raw in text.splitlines():
        line = raw.rstrip()
        sec = _SECTION.match(line)
        if sec:
            current_section = sec.group(1)
            sections[current_section] = []
            current_key = None
            continue
        if current_section is not None:
            if line and not line.lstrip().startswith("--"):
                sections[current_section].append(line)
            continue
        cont = _CONTINUATION.match(line)
        if cont and current_key is not None:
            header[current_key] += " " + cont.group(1).strip()
            continue
        head = _HEADER.match(line)
        if head:
            current_key = head.group(1)
            header[current_key] = head.group(2).strip()
            continue
        current_key = None
    where = f"vge_analytics/sql/{filename}"
    missing = [
        k
        for k in ("metric", "title", "direction", "unit", "level", "grain", "version", "definition")
        if k not in header
    ]
    if missing or set(sections) != {"numerator", "denominator"}:
        raise ValueError(f"{where}: malformed metric file (missing {missing or sections})")
    if header["metric"] != name:
        raise ValueError(f"{where}: declares metric {header['metric']!r}, expected {name!r}")
    return Metric(
        name=name,
        title=header["title"],
        direction=header["direction"],  # type: ignore[arg-type]
        unit=header["unit"],  # type: ignore[arg-type]
        level=header["level"],  # type: ignore[arg-type]
        grain=header["grain"],  # type: ignore[arg-type]
        version=int(header["version"]),
        definition=header["definition"],
        null_rule=header.get("null", ""),
        numerator="\n".join(sections["numerator"]).strip(),
        denominator="\n".join(sections["denominator"]).strip(),
        source=where,
    )


@cache
def registry() -> dict[str, Metric]:
    """All metrics by name, in PROTOCOL §6 order (files are read once, on first use)."""
    out: dict[str, Metric] = {}
    base = resources.files("vge_analytics") / "sql"
    for name in METRIC_NAMES:
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
        f"unknown metric {name!r}{extra}; known metrics: {', '.join(METRIC_NAMES)}"
    )


def resolve_metrics(names: str | list[str] | tuple[str, ...] | None) -> list[Metric]:
    """Metric objects for a list of names (or a comma-separated string); None means all."""
    if names is None:
        return list(registry().values())
    if isinstance(names, str):
        names = [n.strip() for n in names.split(",") if n.strip()]
    if not names:
        raise UnknownMetricError("no metric named; known metrics: " + ", ".join(METRIC_NAMES))
    seen: dict[str, Metric] = {}
    for n in names:
        m = get_metric(n)
        seen.setdefault(m.name, m)
    return list(seen.values())


__all__ = [
    "MAIN_TABLE",
    "METRIC_NAMES",
    "Metric",
    "get_metric",
    "registry",
    "resolve_metrics",
]
