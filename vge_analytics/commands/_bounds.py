"""The bounds of a command's queries (`--memory-limit`, `--timeout`), and the option a person
changes when one stops a query, said at the end of its one line."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

from .._errors import QueryLimitError

HINTS: dict[str, str] = {
    "time": "--timeout sets the limit",
    "memory": "--memory-limit sets the limit",
    "result": "--max-rows shows fewer rows; --format csv or json writes them all",
}
"""What to change when a query is stopped, by the limit that stopped it."""


def hinted(exc: QueryLimitError) -> QueryLimitError:
    """The error with the option that sets its limit at the end of its line."""
    hint = HINTS.get(exc.limit)
    return QueryLimitError(f"{exc} ({hint})" if hint else str(exc), limit=exc.limit)


@contextlib.contextmanager
def command_limits(out: str, timeout: float | None, memory_limit: str | None) -> Iterator[None]:
    """Within the block, every query of the analytics runs within `--memory-limit` (DuckDB's
    limit, and this process's data segment capped around the query; default sized from OUT,
    `store.sized_memory_limit`) and `--timeout`, as a query of `vge sql` does
    (`store.query_limits`); one stopped by a bound ends the command with one line naming the
    metric file whose SQL it holds (else OUT) and the option."""
    from ..store import query_limits, sized_memory_limit

    memory = sized_memory_limit(out, memory_limit)
    try:
        with query_limits(memory=memory, timeout=timeout):
            yield
    except QueryLimitError as exc:
        raise hinted(exc) from None


__all__ = ["HINTS", "command_limits", "hinted"]
