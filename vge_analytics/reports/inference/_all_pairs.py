"""All runs at once (`vge compare OUT --all`): every pair on its common episodes, the
difference of one metric with its clustered interval and a p-value adjusted across the
pairs, and a ranking with its tied groups (a compact letter display).

The runs (or, with `by`, the groups of runs sharing a runs-table value such as `model`) are
ranked by the metric on all their episodes, best first in the metric's direction (ties share
a rank, as `vge rescore` ranks). Each pair (a, b) is taken in ranking order and reported as
`vge compare OUT a b` reports it (B - A, the same draws for the same seed and number of
clusters); a pair with no common episode, or with all of them in one cluster, has no
interval, SE or p-value, is left out of the correction and counts as not distinguishable.
Two runs are distinguishable when their adjusted p-value is below `alpha`; runs sharing a
letter are not.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import polars as pl

from ..._errors import AnalyticsError
from ...metrics import Metric, MetricsSource, metric_set
from ...store import Store, check_same_benchmark, open_store
from .._defaults import DEFAULT_ALPHA, DEFAULT_CORRECTION
from .._ranking import competition_ranks
from ._clusters import DEFAULT_CLUSTER, pooled
from ._letters import TooManyGroupsError, letters_of
from ._paired import (
    PairStatistics,
    check_cluster,
    check_resampling,
    entity_terms,
    finite,
    pair_frames,
    pair_statistics,
    runs_of,
)
from ._significance import adjust_p, check_correction

PAIR_COLUMNS: dict[str, pl.DataType] = {
    "a": pl.String,
    "b": pl.String,
    "n_common": pl.Int64,
    "n_clusters": pl.Int64,
    "A": pl.Float64,
    "B": pl.Float64,
    "diff": pl.Float64,
    "ci_low": pl.Float64,
    "ci_high": pl.Float64,
    "se": pl.Float64,
    "deff": pl.Float64,
    "p_value": pl.Float64,
    "p_adjusted": pl.Float64,
    "significant": pl.Boolean,
}


@dataclass
class AllPairs:
    """Result of `compare_all`: the ranking, the pairs, and what they assume."""

    metric: str
    by: str
    cluster: str
    correction: str
    alpha: float
    seed: int
    resamples: int
    ranking: pl.DataFrame
    """rank, <by>, <metric> (on all the entry's episodes), n_episodes, letters (entries
    sharing a letter are tied)."""
    pairs: pl.DataFrame
    """a, b (a ranked above b), n_common, n_clusters, A, B, diff (B - A), ci_low, ci_high,
    se, deff, p_value, p_adjusted, significant."""
    summary: pl.DataFrame = field(init=False)

    def __post_init__(self) -> None:
        tested = self.pairs.filter(pl.col("p_value").is_not_null()).height
        self.summary = pl.DataFrame(
            [
                {
                    "metric": self.metric,
                    "by": self.by,
                    "entries": self.ranking.height,
                    "pairs": self.pairs.height,
                    "pairs_tested": tested,
                    "significant": int(self.pairs["significant"].sum()),
                    "cluster": self.cluster,
                    "correction": self.correction,
                    "alpha": self.alpha,
                    "seed": self.seed,
                    "resamples": self.resamples,
                }
            ]
        )

    def sections(self) -> dict[str, pl.DataFrame]:
        return {"summary": self.summary, "ranking": self.ranking, "pairs": self.pairs}


def entities_of(store: Store, chosen_runs: Sequence[str] | None, by: str) -> dict[str, list[str]]:
    """{entity: its runs}: each run alone (`by="run_id"`), else the runs sharing a value of
    the runs-table column `by` (a null value reads `∅`)."""
    table = runs_of(store, chosen_runs, [by], "--by")
    entities: dict[str, list[str]] = {}
    for run_id, value in zip(table["run_id"], table[by].cast(pl.String), strict=True):
        entities.setdefault("∅" if value is None else value, []).append(run_id)
    if len(entities) < 2:
        raise AnalyticsError(
            f"comparing every pair needs two or more {by} values, found {len(entities)}"
        )
    return dict(sorted(entities.items()))


def _ranking(
    terms: pl.DataFrame, names: list[str], metric: Metric
) -> tuple[list[str], pl.DataFrame]:
    """(names best first, the ranking rows without letters)."""
    cols = [f"{metric.name}:num", f"{metric.name}:den"]
    totals = terms.group_by("entity").agg(pl.len().alias("n"), *[pl.col(c).sum() for c in cols])
    by_name = {r["entity"]: r for r in totals.iter_rows(named=True)}
    values = {
        n: finite(pooled(by_name[n][cols[0]], by_name[n][cols[1]], metric.scale))
        if n in by_name
        else None
        for n in names
    }
    sign = -1.0 if metric.higher_is_better else 1.0
    ordered = sorted(names, key=lambda n: (values[n] is None, sign * (values[n] or 0.0), n))
    ranks = competition_ranks([values[n] for n in ordered], metric.higher_is_better)
    rows = pl.DataFrame(
        {
            "rank": ranks,
            "entry": ordered,
            "value": [values[n] for n in ordered],
            "n_episodes": [int(by_name[n]["n"]) if n in by_name else 0 for n in ordered],
        },
        schema={"rank": pl.Int64, "entry": pl.String, "value": pl.Float64, "n_episodes": pl.Int64},
    )
    return ordered, rows


def _pair_rows(
    ordered: list[str],
    pairs: list[tuple[str, str, int, int]],
    stats: list[PairStatistics],
    correction: str,
    alpha: float,
) -> pl.DataFrame:
    adjusted = adjust_p([finite(s.p_value[0]) for s in stats], correction)
    rows = []
    for (a, b, n, g), s, p_adj in zip(pairs, stats, adjusted, strict=True):
        diff = finite(s.diff[0])
        rows.append(
            {
                "a": a,
                "b": b,
                "n_common": n,
                "n_clusters": g,
                "A": finite(s.a[0]),
                "B": finite(s.b[0]),
                "diff": diff,
                "ci_low": s.ci_low[0] if diff is not None else None,
                "ci_high": s.ci_high[0] if diff is not None else None,
                "se": finite(s.se[0]),
                "deff": finite(s.deff[0]),
                "p_value": finite(s.p_value[0]),
                "p_adjusted": p_adj,
                "significant": p_adj is not None and p_adj < alpha,
            }
        )
    return pl.DataFrame(rows, schema=PAIR_COLUMNS)


def compare_all(
    out,
    *,
    runs: Sequence[str] | None = None,
    by: str = "run_id",
    metric: str = "SR",
    cluster: str = DEFAULT_CLUSTER,
    correction: str = DEFAULT_CORRECTION,
    alpha: float = DEFAULT_ALPHA,
    seed: int = 0,
    resamples: int = 2000,
    metrics_dir: MetricsSource = None,
    allow_different_benchmarks: bool = False,
) -> AllPairs:
    """Every pair of runs (or of `by` groups) on its common episodes; see the module
    docstring.

    `allow_different_benchmarks`: compare runs replayed against different benchmarks (refused
    by default, `DifferentBenchmarksError`: their episodes share ids, not tasks)."""
    store = open_store(out)
    check_resampling(seed, resamples)
    check_cluster(cluster)
    check_correction(correction)
    if not 0.0 < alpha < 1.0:
        raise AnalyticsError(f"alpha must be between 0 and 1, not {alpha}")
    available = metric_set(metrics_dir)
    (chosen,) = available.resolve([metric])
    entities = entities_of(store, runs, by)
    members = [run for group in entities.values() for run in group]
    check_same_benchmark(store, members, allow=allow_different_benchmarks)
    terms = entity_terms(store, entities, [chosen], available)
    ordered, ranking = _ranking(terms, list(entities), chosen)
    parts = {name: terms.filter(pl.col("entity") == name) for name in ordered}
    paired, keys = [], []
    for i, a in enumerate(ordered):
        for b in ordered[i + 1 :]:
            p = pair_frames(parts[a], parts[b], [chosen], cluster)
            paired.append(p)
            keys.append((a, b, len(p.episodes), len(p.clusters)))
    stats = pair_statistics(paired, [chosen.scale], seed, resamples)
    pairs = _pair_rows(ordered, keys, stats, correction, alpha)
    significant = [(r["a"], r["b"]) for r in pairs.iter_rows(named=True) if r["significant"]]
    try:
        letters = letters_of(ordered, significant)
    except TooManyGroupsError as exc:
        raise AnalyticsError(str(exc)) from None
    ranking = ranking.with_columns(
        letters=pl.Series([letters[n] for n in ordered], dtype=pl.String)
    )
    ranking = ranking.rename({"entry": by, "value": chosen.name})
    pairs = pairs.rename({"a": f"{by}_a", "b": f"{by}_b"})
    return AllPairs(chosen.name, by, cluster, correction, alpha, seed, resamples, ranking, pairs)


__all__ = ["AllPairs", "compare_all", "DEFAULT_ALPHA", "entities_of"]
