"""The Budgets page: the lambda sweep, stored or computed, and its curves."""


from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from pathlib import Path

import polars as pl

import replay
from replay.io import atomic_file

from ..metrics import MetricsSource, fingerprint, metric_set
from ..store import open_store, run_query
from ._replay_output import out_version

SWEEP_AUTO_LIMIT = 12_000
"""Episode replays (episodes x lambdas) a sweep may take without asking (a few seconds)."""
SWEEP_SECONDS_PER_REPLAY = 0.0005
"""Rough cost of one episode replay, for the estimate shown before a large sweep."""


def sweep_size(out: str | Path, runs: Sequence[str], lambdas: Sequence[float]) -> int:
    """Episode replays a sweep of `runs` at `lambdas` takes."""
    counted = run_query(
        open_store(out),
        "SELECT count(*) AS n FROM episodes WHERE list_contains(CAST(? AS VARCHAR[]), run_id)",
        [list(runs)],
    )
    return int(counted["n"][0]) * len(lambdas)


def _sweep_cache_file(
    out: str | Path, runs: Sequence[str], lambdas: Sequence[float], metrics_dir: MetricsSource
) -> Path:
    from ..reports import DEFAULT_SWEEP_METRICS
    from ..synth import cache_dir

    chosen = metric_set(metrics_dir).resolve(list(DEFAULT_SWEEP_METRICS))
    key = json.dumps(
        {
            "out": str(Path(out).resolve()),
            "version": out_version(out),
            "runs": sorted(runs),
            "lambdas": sorted(float(v) for v in lambdas),
            "engine": replay.ENGINE_VERSION,
            "metrics": fingerprint(chosen),
        },
        sort_keys=True,
    )
    name = hashlib.sha256(key.encode()).hexdigest()[:24]
    return cache_dir() / "sweeps" / f"{name}.parquet"


def stored_sweep(
    out: str | Path,
    runs: Sequence[str],
    lambdas: Sequence[float],
    *,
    metrics_dir: MetricsSource = None,
) -> pl.DataFrame | None:
    """A sweep computed earlier for exactly these runs and lambdas on this OUT (same
    manifest, same definitions of SR and SSR), from the on-disk cache, or None."""
    path = _sweep_cache_file(out, runs, lambdas, metrics_dir)
    try:
        return pl.read_parquet(path)
    except (OSError, pl.exceptions.PolarsError):
        return None


def computed_sweep(
    out: str | Path,
    runs: Sequence[str],
    lambdas: Sequence[float],
    *,
    workers: int = 1,
    metrics_dir: MetricsSource = None,
) -> pl.DataFrame:
    """`sweep(out, lambdas, runs=runs)`, kept in the on-disk cache (keyed by OUT, its
    manifest hash, the runs, the lambdas and the metrics' definitions) so the budgets page
    shows it at once next time, across restarts of the app."""
    from ..reports import sweep

    table = sweep(out, sorted(lambdas), runs=sorted(runs), workers=workers, metrics_dir=metrics_dir)
    path = _sweep_cache_file(out, runs, lambdas, metrics_dir)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_file(path, sync=False) as fh:  # a cache: whole, not synced
            table.write_parquet(fh)
    except OSError:
        pass  # a read-only cache only costs the recomputation
    return table


def sweep_curves(sweep: pl.DataFrame, *, relative: bool = False) -> pl.DataFrame:
    """A `sweep` result as the budget figure's lines: group (the run), lambda, SR and `gain`
    (`SR_gain` in percentage points, or `SR_rel_gain` in percent with `relative`)."""
    column = "SR_rel_gain" if relative else "SR_gain"
    return sweep.select(
        pl.col("run_id").alias("group"), "lambda", "SR", pl.col(column).alias("gain")
    )
