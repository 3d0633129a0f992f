"""`--allow-different-benchmarks`: the commands that pair runs' episodes by id (`compare`,
`diff`, `passk`, `power`) refuse runs replayed against different benchmarks unless given it
(`store.check_same_benchmark`); the refusal's line ends with the option."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import typer

from .._errors import DifferentBenchmarksError

ALLOW = "--allow-different-benchmarks"


def allow_option() -> bool:
    """`--allow-different-benchmarks` (a typer option default)."""
    return typer.Option(
        False,
        ALLOW,
        help="Compare runs replayed against different benchmarks (refused by default: their "
        "episodes share ids, not tasks).",
    )


@contextlib.contextmanager
def refusal_hinted() -> Iterator[None]:
    """Within the block, a refusal of runs of different benchmarks says the option."""
    try:
        yield
    except DifferentBenchmarksError as exc:
        raise DifferentBenchmarksError(f"{exc} ({ALLOW} compares them anyway)") from None


__all__ = ["ALLOW", "allow_option", "refusal_hinted"]
