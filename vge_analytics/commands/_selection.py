"""Filters that select nothing, said in one line: a warning on stderr for values no row
holds, exit 1 (`EmptySelectionError`) when the filters select no row at all
(`store.check_selection`; docs/ANALYSIS.md, "Filters that match nothing")."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

from .._errors import EmptySelectionError
from ._incomplete import say

if TYPE_CHECKING:
    from ..store import Filters


def check_where(
    out: str, filters: Filters, items: list[str] | None, *, warn: Callable[[str], None] = say
) -> None:
    """Refuse `--where` options (`items`, as given; `filters` parsed from them) that select
    no row of OUT; warn (`warn`: on stderr) about each value no row holds when the others
    select rows."""
    if not filters:
        return
    from ..store import check_selection

    shown = " ".join(f"--where {item}" for item in items or [])
    check = check_selection(out, filters)
    line = check.line(shown)
    if check.empty:
        raise EmptySelectionError(line)
    if line:
        warn(f"warning: {line}")


__all__ = ["check_where"]
