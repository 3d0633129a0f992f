"""The metrics a computation uses: the built-ins, plus the files of a metrics folder.

A `MetricSet` is an explicit, immutable value passed through the API (`metrics_dir=` of
`metrics`, `episode_terms`, `compare`, `sweep`, `rescore`, `metric_table`): the built-in
metrics (`_registry`), where a folder's file with a built-in's name replaces (overrides) that
built-in in place, and each new name is added after them (sorted by name).

`load_metrics(folder)` reads every `*.sql` file of the folder (not its subfolders; other
files are left alone, so a README can sit beside them), parses each with the format of the
built-ins (`_metric_file`), binds its SQL against the schema of the tables
(`_metric_check`), and refuses two files with one metric name. Every problem of every file
is collected and raised at once as `MetricFileError`, one line each, naming the file and the
line: nothing is skipped. `folder=None` means `$VGE_METRICS_DIR`, and the built-ins alone
when that is unset or empty. A loaded folder is kept per process and read again when one of
its files changes.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import stat
import threading
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Literal

from .._errors import MetricFileError, UnknownMetricError
from ..store import MAX_METRIC_FILE, text_too_large
from ._file import Metric, Problem, parse_metric_file
from ._registry import CONTINUATION_METRICS, MAIN_TABLE, registry

METRICS_DIR_ENV = "VGE_METRICS_DIR"
"""Environment variable naming the default metrics folder."""

Origin = Literal["built-in", "override", "added"]

METRIC_GROUPS: dict[str, tuple[str, ...]] = {
    "main": MAIN_TABLE,
    "continuation": CONTINUATION_METRICS,
}
"""Names that stand for several metrics where metrics are named (`--metrics main`): the
paper's Table 2, and the metrics of continuation runs."""


@dataclass(frozen=True, eq=False)
class MetricSet:
    """Metrics by name, in order: the built-ins (PROTOCOL §6 order, an override in its
    built-in's place), then the added ones sorted by name."""

    metrics: Mapping[str, Metric]
    folder: str | None = None
    """The metrics folder as given (None: the built-ins alone)."""
    _builtins: Mapping[str, Metric] = field(default_factory=registry, repr=False)

    @classmethod
    def builtin(cls) -> MetricSet:
        """The built-in metrics alone."""
        return _builtin_set()

    def __iter__(self) -> Iterator[Metric]:
        return iter(self.metrics.values())

    def __contains__(self, name: object) -> bool:
        return name in self.metrics

    def __len__(self) -> int:
        return len(self.metrics)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self.metrics)

    @property
    def defaults(self) -> tuple[str, ...]:
        """The metrics computed when none are named: every metric but the continuation
        metrics, which only continuation runs give values to (named on request)."""
        return tuple(n for n in self.metrics if n not in CONTINUATION_METRICS)

    def get(self, name: str) -> Metric:
        """The metric called `name`; an unknown name is an error (with a hint)."""
        if name in self.metrics:
            return self.metrics[name]
        folded = {k.casefold(): k for k in self.metrics}
        hint = folded.get(name.casefold())
        extra = f" (did you mean {hint}?)" if hint else ""
        raise UnknownMetricError(
            f"unknown metric {name!r}{extra}; known metrics: {', '.join(self.metrics)}"
        )

    def resolve(self, names: str | Sequence[str] | None) -> list[Metric]:
        """Metrics for a list of names (or a comma-separated string); a group's name
        (`METRIC_GROUPS`) stands for its metrics unless a metric has that name; None means
        the defaults."""
        if names is None:
            return [self.metrics[n] for n in self.defaults]
        if isinstance(names, str):
            names = [n.strip() for n in names.split(",") if n.strip()]
        if not names:
            raise UnknownMetricError("no metric named; known metrics: " + ", ".join(self.metrics))
        chosen: dict[str, Metric] = {}
        for n in names:
            group = METRIC_GROUPS.get(n, ()) if n not in self.metrics else ()
            for name in group or (n,):
                m = self.get(name)
                chosen.setdefault(m.name, m)
        return list(chosen.values())

    def origin(self, name: str) -> Origin:
        """`built-in`, `override` (a folder's file replaces the built-in) or `added`."""
        metric = self.get(name)
        if name not in self._builtins:
            return "added"
        return "built-in" if metric is self._builtins[name] else "override"

    def files_of(self, metrics: Sequence[Metric]) -> tuple[str, ...]:
        """The metric files that define `metrics` (a folder's; none for the built-ins),
        each once, in order: what a message about a query computing them names."""
        files = (m.source for m in metrics if self.origin(m.name) != "built-in")
        return tuple(dict.fromkeys(files))

    @property
    def fingerprint(self) -> str:
        """A hash of every definition (what a cache of computed values is keyed by)."""
        return fingerprint(self.metrics.values())


def fingerprint(metrics: Iterator[Metric] | Sequence[Metric]) -> str:
    """A hash of the definitions of `metrics` (names, sources, SQL, grains, units...)."""
    doc = [
        [m.name, m.source, m.grain, m.unit, m.direction, m.numerator, m.denominator, m.version]
        for m in metrics
    ]
    return hashlib.sha256(json.dumps(doc).encode()).hexdigest()[:16]


@cache
def _builtin_set() -> MetricSet:
    return MetricSet(metrics=registry())


_COMMENT = re.compile(r"^\s*--.*$", re.MULTILINE)


def same_definition(a: Metric, b: Metric) -> bool:
    """Whether two metrics give the same values and ranks: same grain, unit, direction and
    SQL (comment lines and spacing aside). Titles, definitions and versions do not count."""

    def sql(text: str) -> str:
        return " ".join(_COMMENT.sub("", text).split())

    return (a.grain, a.unit, a.direction, sql(a.numerator), sql(a.denominator)) == (
        b.grain,
        b.unit,
        b.direction,
        sql(b.numerator),
        sql(b.denominator),
    )


# ------------------------------------------------------------------------------ loading


def _read_text(path: Path, shown: str, problems: list[Problem]) -> str | None:
    """The text of a metric file, or None after adding its problem: not a regular file, more
    than `MAX_METRIC_FILE` bytes (read no further, so a file that grows costs at most that),
    not UTF-8, unreadable."""
    try:
        # O_NONBLOCK: a FIFO put in the file's place opens at once instead of waiting.
        handle = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except OSError as exc:
        problems.append(Problem(shown, 1, f"cannot be read ({exc.strerror})"))
        return None
    with os.fdopen(handle, "rb") as fh:
        info = os.fstat(handle)
        if not stat.S_ISREG(info.st_mode):
            problems.append(Problem(shown, 1, "not a regular file"))
            return None
        try:
            data = fh.read(MAX_METRIC_FILE + 1)
        except OSError as exc:
            problems.append(Problem(shown, 1, f"cannot be read ({exc.strerror})"))
            return None
    why = text_too_large(max(info.st_size, len(data)), MAX_METRIC_FILE)
    if why is not None:
        problems.append(Problem(shown, 1, f"the file holds {why}"))
        return None
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        problems.append(Problem(shown, 1, f"not UTF-8 text ({exc.reason})"))
        return None


def _metric_files(path: Path) -> list[str]:
    """The names of a folder's metric files, sorted: every *.sql entry but a folder (a link to
    a device or a FIFO is reported when read, not skipped)."""
    return sorted(p.name for p in path.iterdir() if p.name.endswith(".sql") and not p.is_dir())


def folder_fingerprint(folder: str | Path | None = None) -> str | None:
    """A hash of all that `load_metrics(folder)` reads: the folder as given (default
    `$VGE_METRICS_DIR`) and the name and text of each of its metric files, or `built-in`
    for none; None when a file cannot be read as `load_metrics` reads it (it then says
    why). What a folder's metrics are, and whether they pass their checks, follows from
    that and the package's code: a cache keyed by both needs neither DuckDB nor the checks
    to know it still holds."""
    chosen = str(folder) if folder is not None else default_folder()
    if chosen is None:
        return "built-in"
    path = Path(chosen)
    try:
        names = _metric_files(path) if path.is_dir() else []
    except OSError:
        return None
    doc: list[object] = [chosen]
    problems: list[Problem] = []
    for name in names:
        text = _read_text(path / name, str(path / name), problems)
        if text is None:
            return None
        doc.append([name, text])
    return hashlib.sha256(json.dumps(doc).encode()).hexdigest() if names else None


def _read_folder(folder: str) -> tuple[list[Metric], list[Problem]]:
    from ._check import check_metric  # DuckDB binds the SQL: imported when a folder is read

    path = Path(folder)
    if not path.exists():
        raise MetricFileError([f"{folder}: metrics folder not found"])
    if not path.is_dir():
        raise MetricFileError([f"{folder}: not a folder (--metrics-dir takes a folder)"])
    files = _metric_files(path)
    if not files:
        raise MetricFileError([f"{folder}: no metric file (*.sql) in this folder"])
    metrics: list[Metric] = []
    problems: list[Problem] = []
    defined: dict[str, Metric] = {}
    for name in files:
        shown = str(Path(folder) / name)
        text = _read_text(path / name, shown, problems)
        if text is None:
            continue
        metric, found = parse_metric_file(text, shown)
        if metric is None:
            problems.extend(found)
            continue
        bind = check_metric(metric)
        if bind:
            problems.extend(bind)
            continue
        first = defined.get(metric.name)
        if first is not None:
            problems.append(
                Problem(
                    shown,
                    metric.name_line,
                    f"metric {metric.name!r} is also defined in {first.source}:{first.name_line} "
                    "(one file per metric)",
                )
            )
            continue
        defined[metric.name] = metric
        metrics.append(metric)
    return metrics, problems


def _combine(folder: str, metrics: list[Metric]) -> MetricSet:
    builtins = registry()
    by_name = {m.name: m for m in metrics}
    ordered = {name: by_name.get(name, m) for name, m in builtins.items()}
    for name in sorted(set(by_name) - set(builtins)):
        ordered[name] = by_name[name]
    return MetricSet(metrics=ordered, folder=folder)


def _signature(folder: str) -> tuple:
    path = Path(folder)
    try:
        entries = sorted(
            (p.name, p.stat().st_mtime_ns, p.stat().st_size)
            for p in path.iterdir()
            if p.name.endswith(".sql")
        )
        return (path.stat().st_mtime_ns, tuple(entries))
    except OSError:
        return ()


_CACHE: dict[str, tuple[tuple, MetricSet]] = {}
_CACHE_LOCK = threading.Lock()


def default_folder() -> str | None:
    """`$VGE_METRICS_DIR`, or None when it is unset or empty."""
    return os.environ.get(METRICS_DIR_ENV) or None


def load_metrics(folder: str | Path | None = None) -> MetricSet:
    """The built-ins plus the metrics of `folder` (default `$VGE_METRICS_DIR`; neither: the
    built-ins alone). Raises `MetricFileError` listing every problem, one line each."""
    chosen = str(folder) if folder is not None else default_folder()
    if chosen is None:
        return _builtin_set()
    key = str(Path(chosen).resolve())
    sig = _signature(chosen)
    with _CACHE_LOCK:
        hit = _CACHE.get(key)
        if hit is not None and sig and hit[0] == sig and hit[1].folder == chosen:
            return hit[1]
    metrics, problems = _read_folder(chosen)
    if problems:
        raise MetricFileError([str(p) for p in problems], folder=chosen)
    loaded = _combine(chosen, metrics)
    with _CACHE_LOCK:
        _CACHE[key] = (sig, loaded)
    return loaded


MetricsSource = str | Path | MetricSet | None
"""What `metrics_dir=` takes: a folder, a loaded `MetricSet`, or None (the default)."""


def metric_set(source: MetricsSource) -> MetricSet:
    """The `MetricSet` of a `metrics_dir=` argument (see `MetricsSource`)."""
    if isinstance(source, MetricSet):
        return source
    return load_metrics(source)


__all__ = [
    "METRIC_GROUPS",
    "METRICS_DIR_ENV",
    "MetricSet",
    "MetricsSource",
    "Origin",
    "default_folder",
    "fingerprint",
    "folder_fingerprint",
    "load_metrics",
    "metric_set",
    "same_definition",
]
