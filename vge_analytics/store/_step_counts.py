"""The scored steps counted per run, kept beside OUT: what the error shares, the switch classes
and the clicked views add up.

The Errors page's shares (`error_distribution`), the Navigation page's switch classes
(`switch_classes`) and the Grounding page's clicked views (`interaction_views`) each counted
the scored steps of the whole steps table: 13 to 18 s each at 100 times the full benchmark
(91 million steps), on every first visit and for every other grouping or filter. One scan
now counts them together, per run, category, device, view, error type and switch class
(`COUNT_COLUMNS`): every scored step (`scored`), the successful switches (`switches`) and the
interactions (`interactions`), kept in `OUT/.metric-cache/counts_steps-<contents>-<key>.parquet`
(`replay.io.step_counts_path`; `<key>` a hash of the query that counts them). A page then
adds up those rows for its groups and filters: counts are integers, so the sums are the
tables' to the unit, whatever their order; one visit fills what the other two pages read.

They answer a grouping or a filter on run_id, category or a column fixed per run (model,
agent kind, a facet), the pages' choices; any other column is counted on the tables as
before. Keyed, bounded and checked as the other files of the folder: another content of OUT
names another file (the old one is removed), at most `MAX_COUNTS_FILES` are kept, none is
read over `MAX_COUNTS_BYTES`, through a link or when its columns are not the ones written
here (then it is counted again).
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import io
from collections.abc import Sequence
from pathlib import Path

import duckdb
import polars as pl

from replay.io import STEPS_TABLE, atomic_file, step_counts_path

from .._errors import QueryError, QueryLimitError
from ._cache import _where
from ._kept import prune_kept, read_kept
from ._scope import grouped_aggregate, quote_ident, run_level
from ._sql import run_query
from ._store import Store

COUNT_COLUMNS: tuple[str, ...] = (
    "category",
    "device_id",
    "view_before",
    "error_type",
    "switch_class",
)
"""The steps' columns the kept counts are grouped by, besides run_id."""

COUNTS: tuple[tuple[str, str], ...] = (
    ("count(*)", "scored"),
    ("count(*) FILTER (WHERE g.is_switch)", "switches"),
    ("count(*) FILTER (WHERE g.is_interaction)", "interactions"),
)
"""(aggregate over the scored steps, column) of the kept counts."""

ANSWERED: tuple[str, ...] = ("run_id", "category")
"""The columns of the kept counts a page may group or filter by (besides run columns)."""

COUNTS_TABLE = "__step_counts"
"""The name the kept counts are registered under for a query."""

MAX_COUNTS_BYTES = 256 << 20
"""A kept file of counts over this is not read (at 100x the full benchmark: a few MB)."""

MAX_COUNTS_FILES = 2
"""Files of counts kept for one content of OUT (one per version of the counting query)."""


def _query(store: Store) -> tuple[str, list]:
    keys = [(f"g.{quote_ident(c)}", c) for c in COUNT_COLUMNS]
    sql, params = grouped_aggregate(store, STEPS_TABLE, ["run_id"], None, COUNTS, extra_keys=keys)
    return sql + " ORDER BY ALL", params


def answers(store: Store, columns: Sequence[str]) -> bool:
    """Whether the kept counts can be grouped and filtered on `columns`."""
    return all(c in ANSWERED or run_level(store, STEPS_TABLE, c) for c in columns)


def _valid(frame: pl.DataFrame) -> bool:
    schema = frame.schema
    text = ["run_id", *COUNT_COLUMNS]
    return all(schema.get(c) == pl.String for c in text) and all(
        schema.get(c) is not None and schema[c].is_integer() for _, c in COUNTS
    )


def _read(path: Path) -> pl.DataFrame | None:
    data = read_kept(path, MAX_COUNTS_BYTES)
    if data is None:
        return None
    try:
        frame = pl.read_parquet(io.BytesIO(data))
    except (OSError, pl.exceptions.PolarsError, ValueError):
        return None
    return frame if _valid(frame) else None


def _counts(store: Store) -> pl.DataFrame | None:
    """The kept counts of OUT (counted and kept first when missing), or None when OUT keeps
    nothing."""
    out = _where(store)
    if out is None:
        return None
    sql, params = _query(store)
    key = hashlib.sha256(sql.encode()).hexdigest()[:16]
    path = step_counts_path(out, store.contents, key)
    kept = _read(path)
    if kept is not None:
        return kept
    counts = run_query(store, sql, params)
    with contextlib.suppress(OSError, pl.exceptions.PolarsError):
        path.parent.mkdir(exist_ok=True)
        with atomic_file(path, sync=False) as fh:
            counts.write_parquet(fh, compression="zstd")
        prune_kept(path, "counts_steps-*.parquet", MAX_COUNTS_FILES)
    return counts


def counted_steps(store: Store, columns: Sequence[str]) -> Store | None:
    """`store` with OUT's kept step counts registered as `COUNTS_TABLE` (a grain for
    `grouped_aggregate`: run_id, `COUNT_COLUMNS` and the counts of `COUNTS`), or None when
    they cannot answer a grouping or filter on `columns`, or OUT keeps nothing."""
    if not answers(store, columns):
        return None
    try:
        counts = _counts(store)
    except QueryLimitError:
        raise  # a bound stopped it: the tables would be stopped the same way
    except (OSError, duckdb.Error, pl.exceptions.PolarsError, QueryError):
        return None
    if counts is None:
        return None
    derived = dataclasses.replace(store, sources={**store.sources, COUNTS_TABLE: counts.to_arrow()})
    statement = f"DESCRIBE {COUNTS_TABLE}"  # our own name
    with derived.cursor(statement) as cursor:
        rows = cursor.execute(statement).fetchall()
    derived.columns = {**store.columns, COUNTS_TABLE: {r[0]: str(r[1]) for r in rows}}
    return derived


__all__ = [
    "COUNTS",
    "COUNTS_TABLE",
    "COUNT_COLUMNS",
    "MAX_COUNTS_BYTES",
    "MAX_COUNTS_FILES",
    "counted_steps",
]
