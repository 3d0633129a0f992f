"""Repeated runs (`vge passk`): runs of one agent that differ only in their seed, as a group;
per episode, c successes out of the group's n runs; pass@k and pass^k for k = 1..n; the mean
SR over the seeds, its between-seed standard deviation, and an interval that accounts for
both the seeds and the devices (docs/STATISTICS.md).

A group is the runs whose run.json agrees on everything but the run id, `meta.seed` and the
run's totals (PROTOCOL §10.2: what it played and used, which differ between seeds), or, with
`group_by`, on those runs-table columns. It is compared on the episodes every run of it
played. The SR interval is a two-way bootstrap: each resample draws the runs (seeds) and,
independently, the clusters, with replacement, and takes the mean success of every drawn run
on every drawn cluster's episodes (conservative: a crossed design's residual is counted in
both ways). pass@k and pass^k get the cluster bootstrap of their per-episode estimates (the
runs fixed: the estimators already average over every k of the n).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import polars as pl

from replay.semantics import RUN_TOTALS

from ..._errors import AnalyticsError
from ...store import Store, check_same_benchmark, open_store, run_query
from ._clusters import (
    DEFAULT_CLUSTER,
    bootstrap_totals,
    cluster_codes,
    cluster_draws,
    cluster_sums,
    percentile_interval,
)
from ._paired import CLUSTER_COLUMNS, check_cluster, check_resampling, runs_of
from ._passk import pass_at_k, pass_hat_k

SEED_KEY = "seed"
MAX_K = 1000
"""The largest k asked for (rows for k above a group's runs are notes, one per k)."""


def _setting_key(row: dict) -> str:
    meta = json.loads(row["meta"]) if row["meta"] else {}
    settings = {k: v for k, v in meta.items() if k != SEED_KEY and k not in RUN_TOTALS}
    head = [row["model"], row["agent_kind"], row["lambda_run"]]
    return json.dumps([head, settings], sort_keys=True, default=str)


def run_groups(
    store: Store, chosen: Sequence[str] | None = None, group_by: Sequence[str] | None = None
) -> dict[str, list[str]]:
    """{group label (its first run id): its runs, sorted}, groups in label order."""
    table = runs_of(store, chosen, group_by or (), "--group-by")
    keyed: dict[str, list[str]] = {}
    for row in table.sort("run_id").iter_rows(named=True):
        key = json.dumps([row[c] for c in group_by], default=str) if group_by else _setting_key(row)
        keyed.setdefault(key, []).append(row["run_id"])
    return dict(sorted((members[0], members) for members in keyed.values()))


@dataclass
class Repeated:
    """Result of `repeated`: one table per section."""

    groups: pl.DataFrame
    """group, runs, n_runs, n_episodes, n_clusters, SR_mean, SR_sd (between seeds), ci_low,
    ci_high (seeds and clusters resampled), note."""
    passk: pl.DataFrame
    """group, k, n_runs, pass_at_k, pass_at_k_low, pass_at_k_high, pass_hat_k,
    pass_hat_k_low, pass_hat_k_high (percent; clusters resampled), note (k > n)."""
    outcomes: pl.DataFrame
    """group, c, n, episodes: how many episodes were solved by c of the n runs."""
    episodes: pl.DataFrame
    """group, episode_id, device_id, category, n, c."""
    cluster: str
    seed: int
    resamples: int

    def sections(self, per_episode: bool = False) -> dict[str, pl.DataFrame]:
        out = {"groups": self.groups, "passk": self.passk, "outcomes": self.outcomes}
        return out | ({"episodes": self.episodes} if per_episode else {})


def _success_table(store: Store, group: str, members: list[str]) -> pl.DataFrame:
    """group, episode_id, device_id, category, n, c over the episodes every member played."""
    eps = run_query(
        store,
        "SELECT run_id, episode_id, device_id, category, success FROM episodes "
        "WHERE run_id IN (SELECT unnest(CAST(? AS VARCHAR[])))",
        [members],
    )
    return (
        eps.group_by("episode_id", "device_id", "category")
        .agg(pl.len().alias("n"), pl.col("success").cast(pl.Int64).sum().alias("c"))
        .filter(pl.col("n") == len(members))
        .sort("episode_id")
        .select(pl.lit(group).alias("group"), "episode_id", "device_id", "category", "n", "c")
    )


def _two_way_interval(
    success: np.ndarray, codes: np.ndarray, n_clusters: int, seed: int, resamples: int
) -> tuple[float | None, float | None]:
    """Percentile interval of the mean success (percent) with the runs (rows of `success`,
    runs x episodes) and the clusters resampled independently."""
    n_runs = success.shape[0]
    per_cluster = cluster_sums(success.T, codes, n_clusters).T  # runs x G
    sizes = np.bincount(codes, minlength=n_clusters).astype(np.float64)
    seeds = np.random.default_rng([seed, 2])
    draws = np.empty(resamples)
    done = 0
    for counts in cluster_draws(n_clusters, resamples, seed):
        runs_drawn = seeds.multinomial(n_runs, np.full(n_runs, 1.0 / n_runs), size=len(counts))
        num = np.einsum("ri,ig,rg->r", runs_drawn.astype(np.float64), per_cluster, counts)
        den = n_runs * (counts @ sizes)
        draws[done : done + len(counts)] = 100.0 * num / den
        done += len(counts)
    return percentile_interval(draws)


def _passk_rows(
    group: str,
    c: np.ndarray,
    n: int,
    codes: np.ndarray,
    n_clusters: int,
    k_max: int,
    seed: int,
    resamples: int,
) -> list[dict]:
    """pass@k and pass^k (percent) for k = 1..k_max, each with its cluster interval."""
    ks = list(range(1, min(k_max, n) + 1))
    at = {k: np.array([pass_at_k(n, x, k) for x in range(n + 1)])[c] for k in ks}
    hat = {k: np.array([pass_hat_k(n, x, k) for x in range(n + 1)])[c] for k in ks}
    values = np.column_stack([*(at[k] for k in ks), *(hat[k] for k in ks), np.ones(len(c))])
    sums = cluster_sums(values, codes, n_clusters)
    boot = bootstrap_totals([sums], seed, resamples)[0] if n_clusters >= 2 else None
    rows = []
    for i, k in enumerate(ks):
        row = {"group": group, "k": k, "n_runs": n, "note": None}
        for name, col in (("pass_at_k", i), ("pass_hat_k", len(ks) + i)):
            row[name] = 100.0 * float(values[:, col].mean())
            low, high = (None, None)
            if boot is not None:
                low, high = percentile_interval(100.0 * boot[:, col] / boot[:, -1])
            row[f"{name}_low"], row[f"{name}_high"] = low, high
        rows.append(row)
    for k in range(n + 1, k_max + 1):
        rows.append(
            {"group": group, "k": k, "n_runs": n, "note": f"k > n = {n} runs: not estimable"}
        )
    return rows


def _group_note(n_runs: int, n_episodes: int, n_clusters: int, cluster: str) -> str | None:
    if n_episodes == 0:
        return "no episode was played by every run of the group"
    notes = []
    if n_runs == 1:
        notes.append("one run: no spread between seeds (pass@k for k = 1 only)")
    if n_clusters < 2:
        notes.append(f"one {cluster}: no interval")
    return "; ".join(notes) or None


_GROUP_SCHEMA = {
    "group": pl.String,
    "runs": pl.String,
    "n_runs": pl.Int64,
    "n_episodes": pl.Int64,
    "n_clusters": pl.Int64,
    "SR_mean": pl.Float64,
    "SR_sd": pl.Float64,
    "ci_low": pl.Float64,
    "ci_high": pl.Float64,
    "note": pl.String,
}
_PASSK_SCHEMA = {
    "group": pl.String,
    "k": pl.Int64,
    "n_runs": pl.Int64,
    "pass_at_k": pl.Float64,
    "pass_at_k_low": pl.Float64,
    "pass_at_k_high": pl.Float64,
    "pass_hat_k": pl.Float64,
    "pass_hat_k_low": pl.Float64,
    "pass_hat_k_high": pl.Float64,
    "note": pl.String,
}
_EPISODE_SCHEMA = {
    "group": pl.String,
    "episode_id": pl.String,
    "device_id": pl.String,
    "category": pl.String,
    "n": pl.Int64,
    "c": pl.Int64,
}


def _one_group(
    eps: pl.DataFrame,
    group: str,
    members: list[str],
    cluster: str,
    k_max: int,
    seed: int,
    resamples: int,
) -> tuple[dict, list[dict], pl.DataFrame]:
    """(the group's row, its pass@k rows, its per-episode c of n)."""
    n = len(members)
    slot = {run: f"run{i}" for i, run in enumerate(members)}  # a run id may be any text
    mine = eps.filter(pl.col("run_id").is_in(members)).with_columns(
        pl.col("run_id").replace_strict(slot, return_dtype=pl.String)
    )
    wide = (
        mine.pivot(on="run_id", index=["episode_id", "device_id", "category"], values="success")
        .drop_nulls()
        .sort("episode_id")
    )
    columns = [slot[r] for r in members]
    success = wide.select(columns).to_numpy().astype(np.float64).T.reshape(n, wide.height)
    c = success.sum(axis=0).astype(np.int64)
    codes, names = cluster_codes(wide[CLUSTER_COLUMNS[cluster]].to_list())
    per_run = 100.0 * success.mean(axis=1) if wide.height else np.full(n, np.nan)
    usable = wide.height > 0 and len(names) >= 2
    low, high = (
        _two_way_interval(success, codes, len(names), seed, resamples) if usable else (None, None)
    )
    row = {
        "group": group,
        "runs": ",".join(members),
        "n_runs": n,
        "n_episodes": wide.height,
        "n_clusters": len(names),
        "SR_mean": float(per_run.mean()) if wide.height else None,
        "SR_sd": float(per_run.std(ddof=1)) if n > 1 and wide.height else None,
        "ci_low": low,
        "ci_high": high,
        "note": _group_note(n, wide.height, len(names), cluster),
    }
    passk = (
        _passk_rows(group, c, n, codes, len(names), k_max, seed, resamples) if wide.height else []
    )
    per_episode = wide.select(
        pl.lit(group).alias("group"), "episode_id", "device_id", "category",
        pl.lit(n, dtype=pl.Int64).alias("n"), pl.Series("c", c, dtype=pl.Int64),
    )  # fmt: skip
    return row, passk, per_episode


def repeated(
    out,
    *,
    runs: Sequence[str] | None = None,
    group_by: Sequence[str] | None = None,
    k: int | None = None,
    cluster: str = DEFAULT_CLUSTER,
    seed: int = 0,
    resamples: int = 2000,
    allow_different_benchmarks: bool = False,
) -> Repeated:
    """Groups of repeated runs, their pass@k and pass^k (k = 1..k, default each group's n)
    and their mean SR; see the module docstring.

    `allow_different_benchmarks`: group runs replayed against different benchmarks (refused
    by default, `DifferentBenchmarksError`: their episodes share ids, not tasks)."""
    store = open_store(out)
    check_resampling(seed, resamples)
    check_cluster(cluster)
    if k is not None and not 1 <= k <= MAX_K:
        raise AnalyticsError(f"k must be between 1 and {MAX_K}, not {k}")
    groups = run_groups(store, runs, group_by)
    for members in groups.values():  # a group pairs its runs' episodes by id
        check_same_benchmark(store, members, allow=allow_different_benchmarks)
    eps = run_query(
        store,
        "SELECT run_id, episode_id, device_id, category, success FROM episodes "
        "WHERE run_id IN (SELECT unnest(CAST(? AS VARCHAR[])))",
        [[r for members in groups.values() for r in members]],
    )
    rows, passk, per_episode = [], [], []
    for group, members in groups.items():
        k_max = k if k is not None else len(members)
        row, curve, table = _one_group(eps, group, members, cluster, k_max, seed, resamples)
        rows.append(row)
        passk.extend(curve)
        per_episode.append(table)
    episodes = pl.concat(per_episode) if per_episode else pl.DataFrame(schema=_EPISODE_SCHEMA)
    outcomes = _outcomes(episodes, groups)
    return Repeated(
        pl.DataFrame(rows, schema=_GROUP_SCHEMA),
        pl.DataFrame(passk, schema=_PASSK_SCHEMA),
        outcomes,
        episodes.cast(_EPISODE_SCHEMA),
        cluster,
        seed,
        resamples,
    )


def _outcomes(episodes: pl.DataFrame, groups: dict[str, list[str]]) -> pl.DataFrame:
    """group, c, n, episodes for c = 0..n of every group (zeros included)."""
    counts = episodes.group_by("group", "c").agg(pl.len().alias("episodes"))
    found = {(r["group"], r["c"]): r["episodes"] for r in counts.iter_rows(named=True)}
    rows = [
        {"group": g, "c": c, "n": len(m), "episodes": found.get((g, c), 0)}
        for g, m in groups.items()
        for c in range(len(m) + 1)
    ]
    schema = {"group": pl.String, "c": pl.Int64, "n": pl.Int64, "episodes": pl.Int64}
    return pl.DataFrame(rows, schema=schema)


__all__ = ["MAX_K", "Repeated", "repeated", "run_groups", "RUN_TOTALS", "SEED_KEY"]
