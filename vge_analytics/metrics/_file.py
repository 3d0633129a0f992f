"""The metric file format: one `.sql` file, one metric (docs/METRICS.md, "The file format").

The built-in metrics (`vge_analytics/sql/*.sql`) and the files of a user's metrics folder
(`--metrics-dir`) are read by this one parser, with the same rules. A file::

    -- metric: SR-multi
    -- title: Success Rate on multi-goal episodes
    -- direction: higher
    -- unit: percent
    -- grain: episodes
    -- version: 1
    -- definition: Mean over the episodes with more than one goal of success, in
    --   percent.

    -- numerator
    count(*) FILTER (WHERE success AND n_goals > 1)

    -- denominator
    count(*) FILTER (WHERE n_goals > 1)

Header keys (`HEADER_KEYS`): `metric` (a `NAME`), `title`, `direction` (`DIRECTIONS`),
`unit` (`UNITS`), `grain` (`GRAINS`), `version` (a whole number >= 1) and `definition` are
required; `level` (`LEVELS`) and `null` are optional. In the header, a line `-- word: ...`
must use one of these keys (a misspelt key is an error, not a comment), a line `--` + two or
more spaces + text continues the value above it (unless it is itself a `-- key:` line), and
any other `--` line is a comment. After `-- numerator` and `-- denominator`, everything up to
the next section is SQL (comment lines included), except a header line, which is an error
there. Every problem is a `Problem` naming the file and the line; `parse_metric_file`
reports all of a file's problems at once.

Whether the SQL binds (columns exist, it is one aggregate giving numbers) is checked
separately (`_metric_check`), against the schema of the tables.
"""

from __future__ import annotations

import difflib
import re
from dataclasses import dataclass
from typing import Literal

from replay.io import GRAINS

Direction = Literal["higher", "lower"]
Unit = Literal["percent", "ratio", "distance"]
Level = Literal["episode-mean", "step-ratio", "run-level ratio", "goal-ratio"]
Grain = Literal["episodes", "steps", "goals"]

DIRECTIONS: tuple[str, ...] = ("higher", "lower")
UNITS: tuple[str, ...] = ("percent", "ratio", "distance")
LEVELS: tuple[str, ...] = ("episode-mean", "step-ratio", "run-level ratio", "goal-ratio")
SECTIONS: tuple[str, ...] = ("numerator", "denominator")

REQUIRED_KEYS: tuple[str, ...] = (
    "metric",
    "title",
    "direction",
    "unit",
    "grain",
    "version",
    "definition",
)
OPTIONAL_KEYS: tuple[str, ...] = ("level", "null")
HEADER_KEYS: tuple[str, ...] = REQUIRED_KEYS + OPTIONAL_KEYS

_CHOICES: dict[str, tuple[str, ...]] = {
    "direction": DIRECTIONS,
    "unit": UNITS,
    "grain": GRAINS,
    "level": LEVELS,
}
_SCALES = {"percent": 100.0, "ratio": 1.0, "distance": 1.0}

NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_.+-]{0,63}$")
"""A metric name: a letter, then letters, digits, `_ . + -` (64 characters at most)."""

_SECTION = re.compile(r"^--\s*(numerator|denominator)\s*$")
_HEADER = re.compile(r"^--\s*([A-Za-z_][A-Za-z0-9_-]*):(?:\s(.*)|)$")
_CONTINUATION = re.compile(r"^--\s{2,}(\S.*)$")


@dataclass(frozen=True, slots=True)
class Metric:
    """One metric; `numerator` and `denominator` are SQL aggregates over `grain` rows."""

    name: str
    title: str
    direction: Direction
    unit: Unit
    level: Level | None
    """How the metric pools (descriptive; None when the file does not say)."""
    grain: Grain
    version: int
    definition: str
    null_rule: str
    numerator: str
    denominator: str
    source: str
    """The file that defines it: `vge_analytics/sql/<file>` for a built-in, the path of
    the file in the metrics folder otherwise."""
    numerator_line: int = 0
    """Line of the file where the numerator's SQL starts."""
    denominator_line: int = 0
    """Line of the file where the denominator's SQL starts."""
    name_line: int = 0
    """Line of the file's `-- metric:` header."""

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


@dataclass(frozen=True, slots=True)
class Problem:
    """One thing wrong with a metric file, at one line."""

    path: str
    line: int
    message: str

    def __str__(self) -> str:
        return f"{self.path}:{self.line}: {self.message}"


@dataclass
class _Section:
    line: int
    """Line of the `-- numerator` / `-- denominator` marker."""
    body: list[tuple[int, str]]


def _is_sql(text: str) -> bool:
    stripped = text.strip()
    return bool(stripped) and not stripped.startswith("--")


def _section_text(section: _Section) -> tuple[str, int]:
    """(SQL text from its first to its last SQL line, line of the first), or ("", marker)."""
    lines = [(n, t) for n, t in section.body if _is_sql(t)]
    if not lines:
        return "", section.line
    first, last = lines[0][0], lines[-1][0]
    text = "\n".join(t for n, t in section.body if first <= n <= last)
    return text, first


def _did_you_mean(word: str, choices: tuple[str, ...]) -> str:
    """A hint for a slip of case or a typo (`Higher`, `directon`)."""
    folded = {c.casefold(): c for c in choices}
    close = difflib.get_close_matches(word.casefold(), list(folded), n=1, cutoff=0.75)
    return f"; did you mean {folded[close[0]]!r}?" if close else ""


def _check_value(key: str, value: str, line: int, path: str) -> Problem | None:
    if key in _CHOICES:
        choices = _CHOICES[key]
        if value not in choices:
            return Problem(
                path,
                line,
                f"unknown {key} {value!r} (one of: {', '.join(choices)})"
                + _did_you_mean(value, choices),
            )
    elif key == "version":
        if not re.fullmatch(r"[1-9][0-9]{0,8}", value):
            return Problem(path, line, f"version {value!r} is not a whole number of at least 1")
    elif key == "metric":
        if not NAME.match(value):
            return Problem(
                path,
                line,
                f"metric name {value!r} is not a name (a letter, then letters, digits, "
                "'_', '.', '+' or '-'; at most 64 characters)",
            )
    elif key in ("title", "definition") and not value:
        return Problem(path, line, f"the {key} is empty")
    return None


class _Reader:
    """Reads a metric file line by line: the header's keys and values (with the line of
    each), the SQL sections, and every problem on the way."""

    def __init__(self, path: str) -> None:
        self.path = path
        self.header: dict[str, str] = {}
        self.key_lines: dict[str, int] = {}
        self.sections: dict[str, _Section] = {}
        self.problems: list[Problem] = []
        self._key: str | None = None  # the header key a continuation line adds to
        self._section: _Section | None = None  # the section SQL lines go to

    def problem(self, line: int, message: str) -> None:
        self.problems.append(Problem(self.path, line, message))

    def read(self, number: int, raw: str) -> None:
        line = raw.rstrip()
        section = _SECTION.match(line)
        if section:
            self._start_section(number, section.group(1))
        elif self._section is not None:
            self._section_line(number, raw, _HEADER.match(line))
        elif not line.strip():
            self._key = None
        elif not line.lstrip().startswith("--"):
            self.problem(
                number,
                "SQL before the '-- numerator' line (the header holds '-- key: value' lines only)",
            )
            self._key = None
        else:
            self._header_line(number, line)

    def _start_section(self, number: int, name: str) -> None:
        if name in self.sections:
            self.problem(number, f"a second '-- {name}' line (one {name} per file)")
        self._section = _Section(number, [])
        self.sections.setdefault(name, self._section)
        self._key = None

    def _section_line(self, number: int, raw: str, head: re.Match[str] | None) -> None:
        assert self._section is not None
        if head and head.group(1) in HEADER_KEYS:
            self.problem(
                number,
                f"header line '-- {head.group(1)}:' after the SQL sections (the header comes first)",
            )
        else:
            self._section.body.append((number, raw))

    def _header_line(self, number: int, line: str) -> None:
        """A `--` line of the header: a key, the continuation of one, or a comment."""
        head = _HEADER.match(line)
        known = head is not None and head.group(1) in HEADER_KEYS
        cont = _CONTINUATION.match(line)
        if cont and self._key is not None and not known:
            self.header[self._key] += " " + cont.group(1).strip()
            return
        self._key = None
        if head is None:
            return  # a comment
        key, value = head.group(1), (head.group(2) or "").strip()
        if not known:
            self.problem(
                number,
                f"unknown header key {key!r} (known: {', '.join(HEADER_KEYS)})"
                + _did_you_mean(key, HEADER_KEYS),
            )
        elif key in self.header:
            self.problem(
                number, f"header key {key!r} given twice (first at line {self.key_lines[key]})"
            )
        else:
            self.header[key] = value
            self.key_lines[key] = number
            self._key = key

    def check_header(self) -> None:
        """Each value as its key takes it, and every required key there."""
        for key, line in self.key_lines.items():
            problem = _check_value(key, self.header[key], line, self.path)
            if problem is not None:
                self.problems.append(problem)
        missing = [k for k in REQUIRED_KEYS if k not in self.header]
        if missing:
            self.problem(
                1,
                f"missing header {'keys' if len(missing) > 1 else 'key'} "
                f"{', '.join(missing)} (required: {', '.join(REQUIRED_KEYS)})",
            )

    def section_texts(self, end: int) -> dict[str, tuple[str, int]]:
        """(SQL text, its first line) of each section; `end`: the file's last line."""
        texts: dict[str, tuple[str, int]] = {}
        for name in SECTIONS:
            if name not in self.sections:
                self.problem(end, f"no '-- {name}' section (the metric's {name})")
                continue
            texts[name] = _section_text(self.sections[name])
            if not texts[name][0]:
                self.problem(self.sections[name].line, f"the {name} is empty (no SQL after it)")
        return texts


def parse_metric_file(text: str, path: str) -> tuple[Metric | None, list[Problem]]:
    """The metric a file defines, and every problem found in it (the metric is None when
    there is any). `path` is how messages name the file."""
    reader = _Reader(path)
    lines = text.splitlines()
    for number, raw in enumerate(lines, 1):
        reader.read(number, raw)
    reader.check_header()
    texts = reader.section_texts(max(len(lines), 1))
    if reader.problems:
        return None, sorted(reader.problems, key=lambda p: p.line)
    header = reader.header
    metric = Metric(
        name=header["metric"],
        title=header["title"],
        direction=header["direction"],  # type: ignore[arg-type]
        unit=header["unit"],  # type: ignore[arg-type]
        level=header.get("level"),  # type: ignore[arg-type]
        grain=header["grain"],  # type: ignore[arg-type]
        version=int(header["version"]),
        definition=header["definition"],
        null_rule=header.get("null", ""),
        numerator=texts["numerator"][0],
        denominator=texts["denominator"][0],
        source=path,
        numerator_line=texts["numerator"][1],
        denominator_line=texts["denominator"][1],
        name_line=reader.key_lines["metric"],
    )
    return metric, []


__all__ = [
    "DIRECTIONS",
    "GRAINS",
    "HEADER_KEYS",
    "LEVELS",
    "NAME",
    "OPTIONAL_KEYS",
    "REQUIRED_KEYS",
    "SECTIONS",
    "UNITS",
    "Direction",
    "Grain",
    "Level",
    "Metric",
    "Problem",
    "Unit",
    "parse_metric_file",
]
