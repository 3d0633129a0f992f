"""The runs that hold the first rows of a query ordered by run first: a drill-down shows the
first few hundred of 10^7 matching steps, and scanning only the runs that hold them (whose
files are all a run filter opens) reads a fraction of what sorting every match does."""

from __future__ import annotations

from collections.abc import Sequence

from ..store import Store, run_query


def runs_holding_first(
    store: Store, base: str, params: Sequence[object], limit: int
) -> tuple[list[str], int]:
    """(the runs holding the first `limit` rows of `SELECT ... {base} ORDER BY g.run_id, ...`,
    how many rows `base` matches in all), from one count per run. Every row of a run comes
    before every row of a later run in that order, so the first `limit` rows are in the
    smallest runs whose counts reach `limit` (in DuckDB's order of run ids, the order the
    rows are sorted in)."""
    counts = run_query(
        store,
        f"SELECT g.run_id, count(*) AS n {base} GROUP BY g.run_id ORDER BY g.run_id",
        list(params),
    )
    runs: list[str] = []
    held = 0
    for run_id, n in counts.iter_rows():
        if held >= limit:
            break
        runs.append(run_id)
        held += n
    return runs, int(counts["n"].sum())


__all__ = ["runs_holding_first"]
