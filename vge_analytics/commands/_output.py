"""Printing command results: one table or several sections, in the chosen format; the paper's
table as people read it."""

from __future__ import annotations

import os
import shutil
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import typer

from .. import reports, store

if TYPE_CHECKING:
    import polars as pl
    from rich.console import Console

    from ..metrics import MetricSet
    from ..store import Batches

FORMAT_HELP = "Output format: table (for people), json, csv, markdown or latex."


def for_people(df: pl.DataFrame, by: Sequence[str]) -> pl.DataFrame:
    """The metrics table as the paper prints it: run_id dropped from the default grouping
    when each model has one run."""
    if tuple(by) == store.DEFAULT_BY and df["model"].n_unique() == df.height:
        return df.drop("run_id")
    return df


def _console() -> Console:
    from rich.console import Console

    # A terminal: its width (rich squeezes what does not fit, as people expect). Anything
    # else (pipe, file, test runner): wide enough that no column is ever squeezed, whatever
    # COLUMNS says (pytest-xdist sets it to 80 in its workers).
    width = max(shutil.get_terminal_size((240, 24)).columns, 100) if sys.stdout.isatty() else 400
    return Console(highlight=False, soft_wrap=False, width=width)


def finish(console: Console, wrote: str, partly: str | None) -> None:
    """The last lines of a command that writes a directory: what it wrote, then, when some of
    the work could not be done (records quarantined, episodes failed), that in yellow and
    exit code 2 (the rest is written and usable)."""
    console.print(wrote, soft_wrap=True)
    if partly is not None:
        console.print(f"[yellow]{partly}", soft_wrap=True)
        raise typer.Exit(2)


@dataclass(frozen=True, slots=True)
class Printed:
    """What a command prints on stdout: `text`, echoed (a line end added when it has none),
    or, when `console`, written as rich renders it for this terminal (the table format)."""

    text: str
    console: bool = False

    def show(self) -> None:
        if self.console:
            sys.stdout.write(self.text)
            sys.stdout.flush()
        else:
            typer.echo(self.text, nl=not self.text.endswith("\n"))


def console_traits() -> dict[str, object]:
    """What the text of a table rendered for this process's stdout depends on besides the
    table (`_console`: its width, colours, encoding...)."""
    console = _console()
    return {
        "width": console.width,
        "color_system": console.color_system,
        "encoding": console.encoding,
        "is_terminal": console.is_terminal,
        "is_dumb_terminal": console.is_dumb_terminal,
        "no_color": console.no_color,
        "legacy_windows": console.legacy_windows,
    }


def printed(
    df: pl.DataFrame,
    fmt: str,
    *,
    title: str | None = None,
    marks: bool = True,
    metric_set: MetricSet | None = None,
) -> Printed:
    """A table as `emit` prints it in `fmt` (`reports.render`; the table format as the
    console writes it, captured)."""
    out = reports.render(df, fmt, title=title, marks=marks, metric_set=metric_set)
    if isinstance(out, str):
        return Printed(out)
    console = _console()
    with console.capture() as captured:
        console.print(out)
    return Printed(captured.get(), console=True)


def emit(df: pl.DataFrame, fmt: str, **options: Any) -> None:
    """Print a table in `fmt` (`printed`, with its options: title, marks, metric_set)."""
    printed(df, fmt, **options).show()


def emit_stream(result: Batches, fmt: str) -> None:
    """Write a query result in `csv` or `json` as its batches arrive (each is flushed, so a
    reader sees rows while the query runs). A reader that goes away (`| head`) ends it."""

    def frames():
        yield result.frame([])  # the header (csv) even when no row comes
        for batch in result:
            yield result.frame([batch])

    chunks = reports.stream_chunks(frames(), fmt)
    try:
        for chunk in chunks:
            if chunk:
                sys.stdout.write(chunk)
                sys.stdout.flush()
    except BrokenPipeError:
        chunks.close()  # stops the query
        # Python would report the broken pipe again when it flushes stdout at exit.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())


def emit_sections(
    sections: Mapping[str, pl.DataFrame],
    fmt: str,
    *,
    marks: bool = False,
    fixed: bool = False,
    metric_set: MetricSet | None = None,
) -> None:
    """Print named tables; `fixed`: every float with 2 decimals in the formats for people."""
    console = None
    for item in reports.render_sections(sections, fmt, marks=marks, fixed=fixed, metric_set=metric_set):
        if isinstance(item, str):
            typer.echo(item, nl=not item.endswith("\n"))
            if fmt in ("csv", "markdown", "latex"):
                typer.echo("")
        else:
            console = console or _console()
            console.print(item)


__all__ = [
    "FORMAT_HELP",
    "Printed",
    "console_traits",
    "emit",
    "emit_sections",
    "emit_stream",
    "finish",
    "for_people",
    "printed",
]
