"""Rendering DataFrames for the command line: table (rich), json, csv, markdown, latex.

- `json`: a list of objects, one per row, full precision (floats as Python's shortest
  round-trip repr), nulls as null. Multi-table outputs (`errors`, `compare`) print one JSON
  object whose keys are the section names and whose values are such lists.
- `csv`: the rows as they are; multi-table outputs print each section preceded by a
  `# <section>` line and followed by a blank line.
- `markdown` / `latex` / `table`: for people. Metric columns get the paper's arrows in their
  header (up: higher is better) and 2 decimals; with 2 or more groups the best value of each
  metric is bold, and with 3 or more the second best is underlined (ties share the mark).
"""

from __future__ import annotations

import io
import json
import math
import textwrap
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass

import polars as pl

from .._errors import AnalyticsError
from ..metrics import Metric, MetricSet

FORMATS: tuple[str, ...] = ("table", "json", "csv", "markdown", "latex")

SECTIONS_OF_TABLE_2: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("Task Performance", ("SR", "SSR")),
    ("Efficiency", ("SPL", "State-F1")),
    ("Visual Grounding and Perception", ("EIR", "TIR", "VSPS", "GVPE")),
    ("Exploration", ("EER",)),
    ("Generalization", ("PSR",)),
    ("Action Precision", ("AvgDist", "AvgWDist")),
)
"""Column groups of the paper's Table 2 (and, after it, PSR and the distance metrics)."""

MISSING = "\u2013"
"""How a missing value (null, NaN) reads in a table for people: the command line's tables
and the dashboard's alike."""
ARROWS_LEGEND = "\u2191 higher is better, \u2193 lower is better"
"""What the arrows of metric headers mean."""


def metrics_held(names: Sequence[str], metric_set: MetricSet | None = None) -> str:
    """What a table of the metrics `names` holds, for its title: `The paper's metrics`,
    or, with a metrics folder, which of them it overrides and which it adds (`The paper's
    metrics, SR overridden and SR-multi added by mine/`)."""
    chosen = metric_set or MetricSet.builtin()
    shown = [n for n in names if n in chosen]
    by_origin = {
        origin: [n for n in shown if chosen.origin(n) == origin]
        for origin in ("built-in", "override", "added")
    }
    changes = " and ".join(
        f"{', '.join(by_origin[origin])} {word}"
        for origin, word in (("override", "overridden"), ("added", "added"))
        if by_origin[origin]
    )
    if not changes:
        return "The paper's metrics"
    changed = f"{changes} by {chosen.folder}"
    return f"The paper's metrics, {changed}" if by_origin["built-in"] else f"Metrics: {changed}"


def check_format(fmt: str, allowed: Sequence[str] = FORMATS) -> str:
    if fmt not in allowed:
        raise AnalyticsError(f"unknown format {fmt!r}; choose one of {', '.join(allowed)}")
    return fmt


@dataclass(frozen=True)
class Marks:
    """Best/second-best row positions per metric column."""

    best: dict[str, set[int]]
    second: dict[str, set[int]]


def rank_marks(df: pl.DataFrame, metrics: Sequence[Metric]) -> Marks:
    """Rows holding the best and second-best value of each metric (direction-aware)."""
    best: dict[str, set[int]] = {}
    second: dict[str, set[int]] = {}
    for m in metrics:
        if m.name not in df.columns:
            continue
        values = [
            (i, v) for i, v in enumerate(df[m.name].to_list()) if v is not None and math.isfinite(v)
        ]
        if len(values) < 2:
            continue
        distinct = sorted({round(v, 9) for _, v in values}, reverse=m.higher_is_better)
        best[m.name] = {i for i, v in values if round(v, 9) == distinct[0]}
        if len(values) >= 3 and len(distinct) >= 2:
            second[m.name] = {i for i, v in values if round(v, 9) == distinct[1]}
    return Marks(best, second)


_FIXED_COLUMNS = {"A", "B", "diff", "ci_low", "ci_high", "share", "share_a", "share_b", "diff_pp"}


def _fixed(column: str, reg: Mapping[str, Metric]) -> bool:
    """Columns shown with a fixed number of decimals (metric values and their relatives)."""
    return (
        column in reg
        or column in _FIXED_COLUMNS
        or column.endswith(("_gain", "_rel_gain"))
        or column.startswith(tuple(f"{m}_" for m in reg))
    )


def _registry(metric_set: MetricSet | None) -> Mapping[str, Metric]:
    """The metrics whose columns get arrows and marks (default: the built-ins)."""
    return (metric_set or MetricSet.builtin()).metrics


def _fmt_number(value: object, decimals: int | None = 2) -> str:
    """Floats: `decimals` places, or up to 6 significant digits when `decimals` is None."""
    if value is None:
        return MISSING
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        if not math.isfinite(value):
            return MISSING
        return f"{value:.{decimals}f}" if decimals is not None else f"{value:.6g}"
    return str(value)


def _json_default(value: object) -> object:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return str(value)


def _clean(value: object) -> object:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, list):
        return [_clean(v) for v in value]
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items()}
    return value


def to_records(df: pl.DataFrame) -> list[dict]:
    return [{k: _clean(v) for k, v in row.items()} for row in df.to_dicts()]


def render_json(df: pl.DataFrame) -> str:
    return json.dumps(to_records(df), indent=2, ensure_ascii=False, default=_json_default)


def render_csv(df: pl.DataFrame, *, header: bool = True) -> str:
    flat = df.with_columns(
        pl.col(c).cast(pl.List(pl.String)).list.join("|")
        for c, t in df.schema.items()
        if isinstance(t, pl.List)
    )
    buf = io.StringIO()
    flat.write_csv(buf, include_header=header)
    return buf.getvalue()


def stream_chunks(frames: Iterable[pl.DataFrame], fmt: str) -> Iterator[str]:
    """`render(concatenation of frames, fmt)` for `csv` or `json`, one piece per frame (the
    frames are consumed one at a time, so the whole never has to be in memory). `frames`
    holds at least one frame, possibly empty (the columns of an empty result)."""
    if fmt == "csv":
        for i, df in enumerate(frames):
            yield render_csv(df, header=i == 0)
        return
    if fmt != "json":
        raise AnalyticsError(f"format {fmt!r} cannot be streamed; csv and json can")
    rows = 0
    for df in frames:
        pieces = []
        for record in to_records(df):
            body = json.dumps(record, indent=2, ensure_ascii=False, default=_json_default)
            pieces.append(("[\n" if rows == 0 else ",\n") + textwrap.indent(body, "  "))
            rows += 1
        yield "".join(pieces)
    yield "\n]\n" if rows else "[]\n"


def _metric_lookup(df: pl.DataFrame, reg: Mapping[str, Metric]) -> list[Metric]:
    return [reg[c] for c in df.columns if c in reg]


def _header(col: str, reg: Mapping[str, Metric], arrows: str) -> str:
    m = reg.get(col)
    if m is None:
        return col
    if arrows == "latex":
        return f"{col} $\\uparrow$" if m.higher_is_better else f"{col} $\\downarrow$"
    return f"{col} {m.arrow}"


def _cells(
    df: pl.DataFrame, decimals: int, reg: Mapping[str, Metric], fixed: bool = False
) -> list[list[str]]:
    places = [decimals if fixed or _fixed(c, reg) else None for c in df.columns]
    return [[_fmt_number(v, p) for v, p in zip(row, places, strict=True)] for row in df.rows()]


def render_markdown(
    df: pl.DataFrame,
    *,
    decimals: int = 2,
    marks: bool = True,
    fixed: bool = False,
    metric_set: MetricSet | None = None,
) -> str:
    reg = _registry(metric_set)
    metrics = _metric_lookup(df, reg)
    mk = rank_marks(df, metrics) if marks else Marks({}, {})
    headers = [_header(c, reg, "unicode") for c in df.columns]
    cells = _cells(df, decimals, reg, fixed)
    for j, col in enumerate(df.columns):
        for i in mk.best.get(col, ()):
            cells[i][j] = f"**{cells[i][j]}**"
        for i in mk.second.get(col, ()):
            cells[i][j] = f"<u>{cells[i][j]}</u>"
    numeric = [df.schema[c].is_numeric() for c in df.columns]
    align = ["---:" if n else ":---" for n in numeric]

    def line(items: Sequence[str]) -> str:
        return "| " + " | ".join(s.replace("|", "\\|") for s in items) + " |"

    out = [line(headers), "|" + "|".join(align) + "|"]
    out.extend(line(r) for r in cells)
    return "\n".join(out) + "\n"


_KEY_TITLES = {"model": "Model", "run_id": "Run"}

_LATEX_ESCAPES = {
    "\\": r"\textbackslash{}",
    "&": r"\&",
    "%": r"\%",
    "$": r"\$",
    "#": r"\#",
    "_": r"\_",
    "{": r"\{",
    "}": r"\}",
    "~": r"\textasciitilde{}",
    "^": r"\textasciicircum{}",
}


def latex_escape(text: str) -> str:
    return "".join(_LATEX_ESCAPES.get(ch, ch) for ch in text)


def render_latex(
    df: pl.DataFrame,
    *,
    decimals: int = 2,
    marks: bool = True,
    caption: str | None = None,
    label: str | None = None,
    fixed: bool = False,
    metric_set: MetricSet | None = None,
) -> str:
    """A booktabs table shaped like the paper's Table 2 (grouped metric headers)."""
    reg = _registry(metric_set)
    metrics = _metric_lookup(df, reg)
    metric_cols = [m.name for m in metrics]
    key_cols = [c for c in df.columns if c not in reg]
    mk = rank_marks(df, metrics) if marks else Marks({}, {})
    cells = _cells(df, decimals, reg, fixed)
    for j, col in enumerate(df.columns):
        for i in range(len(cells)):
            if col not in reg:
                cells[i][j] = latex_escape(cells[i][j])
        for i in mk.best.get(col, ()):
            cells[i][j] = f"\\textbf{{{cells[i][j]}}}"
        for i in mk.second.get(col, ()):
            cells[i][j] = f"\\underline{{{cells[i][j]}}}"

    spec = "l" * len(key_cols) + "c" * len(metric_cols)
    lines = [
        "\\begin{table*}[t]",
        "  \\centering",
        f"  \\begin{{tabular}}{{{spec}}}",
        "    \\toprule",
    ]
    # Group header row (only for metric columns that follow the paper's section order).
    groups: list[tuple[str, int]] = []
    for title, names in SECTIONS_OF_TABLE_2:
        present = [n for n in names if n in metric_cols]
        if present:
            groups.append((title, len(present)))
    ordered = [n for _, names in SECTIONS_OF_TABLE_2 for n in names if n in metric_cols]
    if metric_cols and ordered == metric_cols and len(groups) > 1:
        head = ["" for _ in key_cols]
        rules = []
        col = len(key_cols) + 1
        for title, width in groups:
            head.append(f"\\multicolumn{{{width}}}{{c}}{{{title}}}")
            rules.append(f"\\cmidrule(lr){{{col}-{col + width - 1}}}")
            col += width
        lines.append("    " + " & ".join(head) + " \\\\")
        lines.append("    " + "".join(rules))
    headers = [latex_escape(_KEY_TITLES.get(c, c)) for c in key_cols]
    headers += [_header(c, reg, "latex") for c in metric_cols]
    lines.append("    " + " & ".join(headers) + " \\\\")
    lines.append("    \\midrule")
    order = key_cols + metric_cols
    index = [df.columns.index(c) for c in order]
    for row in cells:
        lines.append("    " + " & ".join(row[j] for j in index) + " \\\\")
    lines.append("    \\bottomrule")
    lines.append("  \\end{tabular}")
    if caption:
        lines.append(f"  \\caption{{{caption}}}")
    if label:
        lines.append(f"  \\label{{{label}}}")
    lines.append("\\end{table*}")
    return "\n".join(lines) + "\n"


def render_rich(
    df: pl.DataFrame,
    *,
    title: str | None = None,
    decimals: int = 2,
    marks: bool = True,
    fixed: bool = False,
    metric_set: MetricSet | None = None,
):
    """A rich Table (best bold, second underlined, arrows in metric headers)."""
    from rich.table import Table

    reg = _registry(metric_set)
    metrics = _metric_lookup(df, reg)
    mk = rank_marks(df, metrics) if marks else Marks({}, {})
    table = Table(title=title, title_justify="left", show_lines=False)
    for c in df.columns:
        numeric = df.schema[c].is_numeric()
        table.add_column(_header(c, reg, "unicode"), justify="right" if numeric else "left")
    cells = _cells(df, decimals, reg, fixed)
    for i, row in enumerate(cells):
        styled = []
        for j, col in enumerate(df.columns):
            style = ""
            if i in mk.best.get(col, ()):
                style = "bold"
            elif i in mk.second.get(col, ()):
                style = "underline"
            styled.append(f"[{style}]{_esc(row[j])}[/]" if style else _esc(row[j]))
        table.add_row(*styled)
    return table


def _esc(text: str) -> str:
    from rich.markup import escape

    return escape(text)


def render(
    df: pl.DataFrame,
    fmt: str,
    *,
    title: str | None = None,
    marks: bool = True,
    caption: str | None = None,
    metric_set: MetricSet | None = None,
) -> str | object:
    """One table in a format; `table` returns a rich renderable, the others a string.
    `metric_set`: the metrics whose columns get arrows and marks (default: the built-ins)."""
    check_format(fmt)
    if fmt == "json":
        return render_json(df)
    if fmt == "csv":
        return render_csv(df)
    if fmt == "markdown":
        return render_markdown(df, marks=marks, metric_set=metric_set)
    if fmt == "latex":
        return render_latex(df, marks=marks, caption=caption, metric_set=metric_set)
    return render_rich(df, title=title, marks=marks, metric_set=metric_set)


def render_sections(
    sections: Mapping[str, pl.DataFrame],
    fmt: str,
    *,
    marks: bool = False,
    fixed: bool = False,
    metric_set: MetricSet | None = None,
) -> list[str | object]:
    """Several named tables in one format (see the module docstring)."""
    check_format(fmt)
    if fmt == "json":
        doc = {name: to_records(df) for name, df in sections.items()}
        return [json.dumps(doc, indent=2, ensure_ascii=False, default=_json_default)]
    out: list[str | object] = []
    options = {"marks": marks, "fixed": fixed, "metric_set": metric_set}
    for name, df in sections.items():
        if fmt == "csv":
            out.append(f"# {name}\n" + render_csv(df))
        elif fmt == "markdown":
            out.append(f"### {name}\n\n" + render_markdown(df, **options))
        elif fmt == "latex":
            out.append(f"% {name}\n" + render_latex(df, **options))
        else:
            out.append(render_rich(df, title=name, **options))
    return out


__all__ = [
    "ARROWS_LEGEND",
    "FORMATS",
    "MISSING",
    "SECTIONS_OF_TABLE_2",
    "check_format",
    "latex_escape",
    "metrics_held",
    "rank_marks",
    "render",
    "render_csv",
    "render_json",
    "render_latex",
    "render_markdown",
    "render_rich",
    "render_sections",
    "to_records",
]
