"""The scored steps counted per run, kept beside OUT: what the error shares, the switch classes
and the clicked views add up.

The Errors page's shares (`error_distribution`), the Navigation page's switch classes
(`switch_classes`) and the Grounding page's clicked views (`interaction_views`) each count
the scored steps of the whole steps table: 3 to 18 s each at 100 times the full benchmark
(91 million steps), on every first visit and again for every other grouping or filter. The
first count of each (`PARTS`) is now made per run and category and kept, in
`OUT/.metric-cache/counts_<part>-<contents>-<key>.parquet` (`replay.io.step_counts_path`;
`<key>` a hash of the query that counts): the errors per error type, the successful switches
per switch class, the interactions per device and view. A page then adds up the kept rows
for its groups and filters: counts are integers, so the sums are the tables' to the unit,
whatever their order. (One scan for the three, grouped by all their columns or by grouping
sets, took longer at 100x than the three scans together: 30 to 36 s.)

The first count reads the steps files by polars (`_scan_counts.count_steps`: the same rows,
with less work than DuckDB over the Arrow dataset, which made a first visit 1.2 to 3 s slower
than the page's own query had been), else, where polars cannot give the dataset's rows, by
DuckDB's query (`_query`, whose text names the kept file).

A new content of OUT (a run replayed into it, replayed again, changed by hand or removed)
counts only the runs whose steps files changed (`_recounted`): the file keeps each run's key
(`_run_keys`: its files' paths, sizes and modification times, in the footer), and the rows
of every run whose key is the same are taken from the file kept for the earlier content (a
run's rows are its own files' alone); the others are counted from their files only (polars
over those runs' files, or DuckDB's query of those runs), a removed run's rows dropped. The
same rows in the same order as counting all (at 100x, one run added or removed: 0.06 to
0.74 s instead of 4 to 6.6 s a part, docs/PERFORMANCE.md). An earlier file that is not one
of ours (no keys, keys or columns not ours, a run's rows without a key, a link, over the
bound) is not used: all is counted.

They answer a grouping or a filter on run_id, category or a column fixed per run (model,
agent kind, a facet), the pages' choices; any other column is counted on the tables as
before. Keyed, bounded and checked as the other files of the folder: another content of OUT
names another file (the part's old one is removed), at most `MAX_COUNTS_FILES` are kept per
part, none is read over `MAX_COUNTS_BYTES`, through a link or when its columns are not the
ones written here (then it is counted again).
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from pathlib import Path
from typing import NamedTuple

import msgspec
import polars as pl

from replay.io import PARTITION_KEY, STEPS_TABLE, step_counts_path

from ._cache import _where, with_tables
from ._kept import kept_frame, read_kept_frame, unless_failed
from ._run_keys import RUN_KEYS, earlier, run_keys
from ._scan_counts import count_steps
from ._scope import build_scope, quote_ident, run_level
from ._sql import run_query
from ._store import Store


class Part(NamedTuple):
    """One kept count of the scored steps: per run, category and `columns`, the steps as
    `name`, of those where the boolean column `where` is true (None: all), counting only
    those where the boolean column `only` is true (None: all; the groups stay, counted 0)."""

    columns: tuple[str, ...]
    name: str
    where: str | None = None
    only: str | None = None

    @property
    def keys(self) -> tuple[str, ...]:
        return ("run_id", "category", *self.columns)


PARTS: dict[str, Part] = {
    "errors": Part(("error_type",), "scored"),
    "switches": Part(("switch_class",), "switches", only="is_switch"),
    "views": Part(("device_id", "view_before"), "interactions", where="is_interaction"),
}
"""The counts kept, a file each: what `error_distribution`, `switch_classes` and
`interaction_views` add up."""

ANSWERED: tuple[str, ...] = ("run_id", "category")
"""The columns of the kept counts a page may group or filter by (besides run columns)."""

COUNTS_TABLE = "__step_counts"
"""The name the kept counts are registered under for a query."""

MAX_COUNTS_BYTES = 256 << 20
"""A kept file of counts over this is not read (at 100x the full benchmark: a few MB)."""

MAX_COUNTS_FILES = 2
"""Files of a part kept for one content of OUT (one per version of the counting query)."""


def _query(store: Store, part: Part, runs: Sequence[str] | None = None) -> tuple[str, list]:
    """The scored steps (and `part.where`) counted per run, category and `part.columns` (of
    `runs` only; None: all)."""
    scope = build_scope(store, STEPS_TABLE, [], None if runs is None else {"run_id": list(runs)})
    keys = ", ".join(f"g.{quote_ident(c)}" for c in part.keys)
    count = "count(*)" if part.only is None else f"count(*) FILTER (WHERE g.{part.only})"
    where = "TRUE" if part.where is None else f"g.{part.where}"
    sql = (
        f"SELECT {keys}, {count} AS {quote_ident(part.name)} "
        f"FROM {scope.from_sql} WHERE {scope.where_sql} AND {where} "
        f"GROUP BY {keys} ORDER BY ALL"
    )
    return sql, list(scope.params)


def answers(store: Store, columns: Sequence[str]) -> bool:
    """Whether the kept counts can be grouped and filtered on `columns`."""
    return all(c in ANSWERED or run_level(store, STEPS_TABLE, c) for c in columns)


def _valid(frame: pl.DataFrame, part: Part) -> bool:
    schema = frame.schema
    return all(schema.get(c) == pl.String for c in part.keys) and (
        schema.get(part.name) is not None and schema[part.name].is_integer()
    )


def _read(path: Path, part: Part) -> pl.DataFrame | None:
    frame = read_kept_frame(path, MAX_COUNTS_BYTES)
    return frame if frame is not None and _valid(frame, part) else None


def _counted(store: Store, part: Part, runs: Sequence[str] | None = None) -> pl.DataFrame:
    """The counts `part` of the steps (of `runs` only; None: all): read from the steps files
    by polars where it can (`count_steps`: faster than DuckDB over the Arrow dataset), else
    by `_query`; the same rows."""
    counted = count_steps(store, part.keys, part.name, part.where, part.only, runs)
    return counted if counted is not None else run_query(store, *_query(store, part, runs))


def _recounted(store: Store, part: Part, path: Path, keys: dict[str, str]) -> pl.DataFrame:
    """The counts `part` of the steps, the rows of each run whose files are those of the
    counts kept for an earlier content of OUT (`_run_keys.earlier`) taken from them, the
    other runs' counted (`_counted`); `keys` is given the runs' keys now (`run_keys`,
    looked at before any file is read). The same rows, in the same order, as counting all:
    each run's rows are its files' alone, so a run's kept rows are its count, and the
    rows are sorted by run first (`_merged`)."""
    now = run_keys(store, [*part.keys, "truncated", *filter(None, (part.where, part.only))])
    keys.update(now or {})
    found = earlier(path, MAX_COUNTS_BYTES) if now else None
    if found is None or not _valid(found[0], part):
        return _counted(store, part)
    frame, before = found
    same = {run for run, key in now.items() if before.get(run) == key}
    if not same:
        return _counted(store, part)
    kept = frame.select(*part.keys, part.name).filter(pl.col(PARTITION_KEY).is_in(sorted(same)))
    fresh = [run for run in now if run not in same]
    if not fresh:
        return kept
    return _merged(kept, _counted(store, part, fresh))


def _merged(kept: pl.DataFrame, counted: pl.DataFrame) -> pl.DataFrame:
    """The rows of `kept` and `counted` (each sorted by run first, of different runs) sorted
    by run, each run's rows in their order: each counted run's rows put where it falls
    among the kept runs' (slices: 2 million kept rows merged in 0.2 s, sliced in 1 ms)."""
    kept = kept.cast(counted.schema)
    runs = kept.get_column(PARTITION_KEY)
    pieces, done = [], 0
    for (run,), rows in counted.group_by(PARTITION_KEY, maintain_order=True):
        at = runs.search_sorted(run, side="left")
        pieces += [kept.slice(done, at - done), rows]
        done = at
    return pl.concat([*pieces, kept.slice(done)], rechunk=len(pieces) > 64)


def _counts(store: Store, name: str) -> pl.DataFrame | None:
    """The kept counts `name` of OUT (counted and kept first when missing, each run's
    rows reused from those of an earlier content where its files are the same:
    `_recounted`), or None when OUT keeps nothing."""
    out = _where(store)
    if out is None:
        return None
    part = PARTS[name]
    sql, _ = _query(store, part)
    key = hashlib.sha256(sql.encode()).hexdigest()[:16]
    path = step_counts_path(out, name, store.contents, key)
    keys: dict[str, str] = {}
    return kept_frame(
        path,
        lambda at: _read(at, part),
        lambda: _recounted(store, part, path, keys),
        f"counts_{name}-*.parquet",
        MAX_COUNTS_FILES,
        lambda: {RUN_KEYS: msgspec.json.encode(keys).decode()} if keys else {},
    )


def counted_steps(store: Store, part: str, columns: Sequence[str]) -> Store | None:
    """`store` with OUT's kept step counts `part` (of `PARTS`) registered as `COUNTS_TABLE`
    (a grain for `grouped_aggregate`: run_id, category, the part's columns and its count),
    or None when they cannot answer a grouping or filter on `columns`, or OUT keeps
    nothing."""
    if not answers(store, columns):
        return None
    counts = unless_failed(lambda: _counts(store, part))
    if counts is None:
        return None
    return with_tables(store, {COUNTS_TABLE: counts.to_arrow()})


__all__ = [
    "COUNTS_TABLE",
    "PARTS",
    "MAX_COUNTS_BYTES",
    "MAX_COUNTS_FILES",
    "counted_steps",
]
