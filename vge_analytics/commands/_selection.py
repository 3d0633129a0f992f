"""Filters that select nothing, said in one line: a warning on stderr for values no row
holds, exit 1 (`EmptySelectionError`) when the filters select no row at all
(`store.check_selection`; docs/ANALYSIS.md, "Filters that match nothing")."""

from __future__ import annotations

from typing import TYPE_CHECKING

import typer

from .._errors import EmptySelectionError

if TYPE_CHECKING:
    from ..store import Filters


def check_where(out: str, filters: Filters, items: list[str] | None) -> None:
    """Refuse `--where` options (`items`, as given; `filters` parsed from them) that select
    no row of OUT; warn about each value no row holds when the others select rows."""
    if not filters:
        return
    from ..store import check_selection

    shown = " ".join(f"--where {item}" for item in items or [])
    check = check_selection(out, filters)
    line = check.line(shown)
    if check.empty:
        raise EmptySelectionError(line)
    if line:
        typer.echo(f"warning: {line}", err=True)


__all__ = ["check_where"]
