"""Two runs' trajectories side by side (`vge diff`): where, episode by episode, the two
replays part, and where each run first erred.

The per-episode rows come from one query, `sql/diff.sql`, over the store (so an OUT in object
storage works like a local one): the steps of both runs are paired by step number and the
first pair whose `state_after` or `view_after` differs, or that only one run has, is the
first difference. The summary (outcomes, the median first difference, the error types at
each run's first error) is computed from those rows.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import polars as pl

from .._errors import CommonEpisodesError
from .._nearest import nearest
from ..store import check_runs, check_same_benchmark, open_store, run_query
from ._queries import query_text
from ._taxonomy import ERROR_LABELS, ERROR_TYPES

DIFF_COLUMNS: tuple[str, ...] = (
    "episode_id",
    "steps_a",
    "steps_b",
    "success_a",
    "success_b",
    "first_error_a",
    "first_error_b",
    "first_difference",
)
"""The columns of a diff row, in order (what `--format json` prints for each episode)."""

NO_ERROR = "(no error)"
"""How the summary names the episodes of a run without any error."""

_SHOWN_EPISODES = 5
"""Episode ids an error message names before it says how many more there are."""


@dataclass(frozen=True)
class Diff:
    """The result of `diff`: one row per common episode, and the summary built from them."""

    run_a: str
    run_b: str
    rows: pl.DataFrame
    """`DIFF_COLUMNS`, then `first_error_type_a` and `first_error_type_b` (the error type
    at that step) and `device_id`, sorted by episode_id."""

    @property
    def episodes(self) -> pl.DataFrame:
        """The diff rows (`DIFF_COLUMNS`)."""
        return self.rows.select(DIFF_COLUMNS)

    def outcomes(self) -> pl.DataFrame:
        """Episodes by (success_a, success_b): all four pairs, solved by both first."""
        grid = pl.DataFrame(
            {"success_a": [True, True, False, False], "success_b": [True, False, True, False]}
        )
        counts = self.rows.group_by("success_a", "success_b").agg(episodes=pl.len())
        return grid.join(counts, on=["success_a", "success_b"], how="left").with_columns(
            pl.col("episodes").fill_null(0).cast(pl.Int64)
        )

    def differences(self) -> pl.DataFrame:
        """One row: common episodes, how many replay identically, how many differ, and the
        median first difference over those that differ (null when none does)."""
        differing = self.rows["first_difference"].drop_nulls()
        median = differing.median() if differing.len() else None
        return pl.DataFrame(
            {
                "episodes": [self.rows.height],
                "identical": [self.rows.height - differing.len()],
                "differing": [differing.len()],
                "median_first_difference": [median],
            },
            schema={
                "episodes": pl.Int64,
                "identical": pl.Int64,
                "differing": pl.Int64,
                "median_first_difference": pl.Float64,
            },
        )

    def first_errors(self) -> pl.DataFrame:
        """Per error type (the paper's order), the episodes of each run whose first error is
        of that type; types neither run has at its first error are left out; a last row
        counts the episodes without any error."""
        counts = []
        for side in ("a", "b"):
            counts.append(
                self.rows.select(pl.col(f"first_error_type_{side}").fill_null(NO_ERROR))
                .to_series()
                .value_counts(name=f"episodes_{side}")
                .rename({f"first_error_type_{side}": "error_type"})
            )
        order = [*ERROR_TYPES, NO_ERROR]
        merged = counts[0].join(counts[1], on="error_type", how="full", coalesce=True)
        return (
            merged.with_columns(
                pl.col("episodes_a", "episodes_b").fill_null(0).cast(pl.Int64),
                label=pl.col("error_type").replace_strict(
                    {**ERROR_LABELS, NO_ERROR: NO_ERROR}, return_dtype=pl.String
                ),
                __order=pl.col("error_type").replace_strict(
                    {t: i for i, t in enumerate(order)}, return_dtype=pl.Int64
                ),
            )
            .sort("__order")
            .select("error_type", "label", "episodes_a", "episodes_b")
        )

    def sections(self) -> dict[str, pl.DataFrame]:
        """The rows, then the summary, as named tables (what the CLI prints for people)."""
        a, b = self.run_a, self.run_b
        return {
            f"A = {a}, B = {b}: {self.rows.height} common episodes": self.episodes,
            "episodes by (success_a, success_b)": self.outcomes(),
            "first difference (step, from 0)": self.differences(),
            "error type at each run's first error (episodes)": self.first_errors(),
        }


def _named(ids: Sequence[str]) -> str:
    shown = ", ".join(repr(i) for i in ids[:_SHOWN_EPISODES])
    more = len(ids) - _SHOWN_EPISODES
    return shown + (f" and {more} more" if more > 0 else "")


def diff(
    out,
    run_a: str,
    run_b: str,
    *,
    episodes: Sequence[str] | None = None,
    allow_different_benchmarks: bool = False,
) -> Diff:
    """Compare the trajectories of runs A and B on the episodes both replayed (or on
    `episodes`, which must all be common), one row per episode (see `DIFF_COLUMNS`).

    Raises `UnknownRunError` for a run not in OUT, `CommonEpisodesError` when the runs share
    no episode or `episodes` names one they do not share, `DifferentBenchmarksError` when
    they were replayed against different benchmarks (unless `allow_different_benchmarks`)."""
    store = open_store(out)
    check_runs(store, [run_a, run_b])
    check_same_benchmark(store, [run_a, run_b], allow=allow_different_benchmarks)
    wanted = None if episodes is None else sorted(set(episodes))
    rows = run_query(store, query_text("diff"), [run_a, run_b, wanted])
    if wanted is not None and rows.height < len(wanted):
        missing = sorted(set(wanted) - set(rows["episode_id"]))
        common = run_query(
            store,
            "SELECT episode_id FROM episodes WHERE run_id = ? "
            "INTERSECT SELECT episode_id FROM episodes WHERE run_id = ? ORDER BY episode_id",
            [run_a, run_b],
        )["episode_id"]
        close = nearest(missing[0], common.to_list())
        raise CommonEpisodesError(
            f"not replayed in both {run_a!r} and {run_b!r}: episode {_named(missing)}"
            + (f"; nearest{'' if len(missing) == 1 else f' {missing[0]!r}'}: " if close else "")
            + ", ".join(close)
        )
    if rows.height == 0:
        raise CommonEpisodesError(f"runs {run_a!r} and {run_b!r} have no episode in common")
    return Diff(run_a, run_b, rows)


__all__ = ["DIFF_COLUMNS", "NO_ERROR", "Diff", "diff"]
