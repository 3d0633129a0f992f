"""Printing command results: one table or several sections, in the chosen format."""

from __future__ import annotations

import shutil
import sys
from collections.abc import Mapping

import polars as pl
import typer
from rich.console import Console

from ._format import render, render_sections

FORMAT_HELP = "Output format: table (for people), json, csv, markdown or latex."


def _console() -> Console:
    # A terminal: its width (rich squeezes what does not fit, as people expect). Anything
    # else (pipe, file, test runner): wide enough that no column is ever squeezed, whatever
    # COLUMNS says (pytest-xdist sets it to 80 in its workers).
    width = max(shutil.get_terminal_size((240, 24)).columns, 100) if sys.stdout.isatty() else 400
    return Console(highlight=False, soft_wrap=False, width=width)


def emit(df: pl.DataFrame, fmt: str, *, title: str | None = None, marks: bool = True) -> None:
    out = render(df, fmt, title=title, marks=marks)
    if isinstance(out, str):
        typer.echo(out, nl=not out.endswith("\n"))
    else:
        _console().print(out)


def emit_sections(
    sections: Mapping[str, pl.DataFrame], fmt: str, *, marks: bool = False, fixed: bool = False
) -> None:
    """Print named tables; `fixed`: every float with 2 decimals in the formats for people."""
    console = None
    for item in render_sections(sections, fmt, marks=marks, fixed=fixed):
        if isinstance(item, str):
            typer.echo(item, nl=not item.endswith("\n"))
            if fmt in ("csv", "markdown", "latex"):
                typer.echo("")
        else:
            console = console or _console()
            console.print(item)


__all__ = ["FORMAT_HELP", "emit", "emit_sections"]
