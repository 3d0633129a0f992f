"""Printing command results: one table or several sections, in the chosen format."""

from __future__ import annotations

import shutil
from collections.abc import Mapping

import polars as pl
import typer
from rich.console import Console

from ._format import render, render_sections

FORMAT_HELP = "Output format: table (for people), json, csv, markdown or latex."


def _console() -> Console:
    # Not a terminal (pipe, file, test runner): wide enough that tables are not squeezed.
    width = shutil.get_terminal_size((240, 24)).columns
    return Console(highlight=False, soft_wrap=False, width=max(width, 100))


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
