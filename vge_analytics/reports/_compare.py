"""Paired comparison of two runs on the episodes both have (human vs VLM, model vs model).

- Metrics: each registry metric on the common episodes for run A and run B, the difference
  B - A, and a paired bootstrap 95% percentile interval of the difference: the common
  episodes are resampled with replacement (the same resample for both runs, seeded), and each
  resample's metric is the pooled `scale * sum(num) / sum(den)` of the resampled episodes'
  per-episode terms (`episode_terms`), so step-ratio and goal-ratio metrics are resampled by
  episode, as the unit of the pairing.
- McNemar's exact test on episode success: b = episodes only A solved, c = episodes only B
  solved; under H0 each discordant pair is A-only with probability 1/2, so the two-sided
  p-value is min(1, 2 * P(X <= min(b, c))) for X ~ Binomial(b + c, 1/2) (1 when b + c = 0).
- The error-type distribution of each run on the common episodes and the difference B - A
  in percentage points (the paper's human vs Gemini table).
- The episodes that flip: solved by A only, solved by B only.
- Whether each run is complete (run.json's word, PROTOCOL §7.5): a run cut short is compared
  on the episodes it has, and the summary says so.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from fractions import Fraction
from math import comb

import numpy as np
import polars as pl

from .._errors import AnalyticsError
from ..metrics import MetricsSource, episode_terms, metric_set
from ..store import check_runs, open_store, run_query
from ._completeness import completeness
from ._taxonomy import ERROR_LABELS, error_distribution

DEFAULT_RESAMPLES = 2000
DEFAULT_SEED = 0
_CHUNK = 250


def mcnemar_exact(b: int, c: int) -> float:
    """Two-sided exact McNemar p-value from the discordant counts b and c."""
    n = b + c
    if n == 0:
        return 1.0
    k = min(b, c)
    tail = sum(comb(n, i) for i in range(k + 1))
    return float(min(Fraction(1), Fraction(2 * tail, 2**n)))


@dataclass
class Comparison:
    """Result of `compare`: scalars plus one polars DataFrame per section."""

    run_a: str
    run_b: str
    model_a: str
    model_b: str
    n_common: int
    n_only_a: int
    n_only_b: int
    seed: int
    resamples: int
    metrics: pl.DataFrame
    """metric, direction, unit, A, B, diff (B - A), ci_low, ci_high (95% paired bootstrap)."""
    mcnemar: pl.DataFrame
    """One row: n_common, both, a_only (b), b_only (c), neither, p_value."""
    errors: pl.DataFrame
    """error_group, error_type, label, count_a, count_b, share_a, share_b, diff_pp (B - A)."""
    flips: pl.DataFrame
    """episode_id, device_id, category, direction ('A_only' or 'B_only')."""
    complete_a: bool | None = None
    complete_b: bool | None = None
    """run.json's `complete` of each run (None: it does not say)."""
    summary: pl.DataFrame = field(init=False)
    """One row describing the pairing (runs, models, whether each is complete, episode
    counts, seed, resamples)."""

    def __post_init__(self) -> None:
        self.summary = pl.DataFrame(
            [
                {
                    "run_a": self.run_a,
                    "model_a": self.model_a,
                    "run_b": self.run_b,
                    "model_b": self.model_b,
                    "complete_a": self.complete_a,
                    "complete_b": self.complete_b,
                    "n_common": self.n_common,
                    "n_only_a": self.n_only_a,
                    "n_only_b": self.n_only_b,
                    "seed": self.seed,
                    "resamples": self.resamples,
                }
            ],
            schema_overrides={"complete_a": pl.Boolean, "complete_b": pl.Boolean},
        )

    def sections(self) -> dict[str, pl.DataFrame]:
        """Every table of the comparison, by name (what the CLI prints)."""
        return {
            "summary": self.summary,
            "metrics": self.metrics,
            "mcnemar": self.mcnemar,
            "errors": self.errors,
            "flips": self.flips,
        }


def _pooled(num: np.ndarray, den: np.ndarray, scale: float) -> np.ndarray:
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(den > 0, scale * num / np.where(den > 0, den, 1.0), np.nan)


def _value(x: float) -> float | None:
    return None if x is None or not np.isfinite(x) else float(x)


def compare(
    out,
    run_a: str,
    run_b: str,
    *,
    metrics: str | list[str] | None = None,
    seed: int = DEFAULT_SEED,
    resamples: int = DEFAULT_RESAMPLES,
    metrics_dir: MetricsSource = None,
) -> Comparison:
    """Compare run B with run A on their common episodes (see the module docstring).

    `metrics_dir`: a metrics folder (or `MetricSet`) whose metrics are compared; default
    `$VGE_METRICS_DIR`, else the built-ins."""
    store = open_store(out)
    if resamples < 1:
        raise AnalyticsError(f"resamples must be at least 1, not {resamples}")
    check_runs(store, [run_a, run_b])
    if run_a == run_b:
        raise AnalyticsError(f"compare needs two different runs, got {run_a!r} twice")
    available = metric_set(metrics_dir)
    chosen = available.resolve(metrics)

    eps = run_query(
        store,
        "SELECT run_id, model, episode_id, device_id, category, success FROM episodes "
        "WHERE run_id IN (SELECT unnest(CAST(? AS VARCHAR[])))",
        [[run_a, run_b]],
    )
    a_eps = eps.filter(pl.col("run_id") == run_a)
    b_eps = eps.filter(pl.col("run_id") == run_b)
    ids_a, ids_b = set(a_eps["episode_id"]), set(b_eps["episode_id"])
    common = sorted(ids_a & ids_b)
    if not common:
        raise AnalyticsError(f"runs {run_a!r} and {run_b!r} have no episode in common")
    model_a = str(a_eps["model"][0])
    model_b = str(b_eps["model"][0])

    # ---- metrics with paired bootstrap CIs
    terms = episode_terms(
        store, [m.name for m in chosen], where={"run_id": [run_a, run_b]}, metrics_dir=available
    )
    frame = pl.DataFrame({"episode_id": common})
    aligned = {}
    for run in (run_a, run_b):
        part = terms.filter(pl.col("run_id") == run).drop("run_id")
        aligned[run] = frame.join(part, on="episode_id", how="left").fill_null(0)
    rng = np.random.default_rng(seed)
    n = len(common)
    cols = []
    for m in chosen:
        for run in (run_a, run_b):
            for part in ("num", "den"):
                cols.append(aligned[run][f"{m.name}:{part}"].cast(pl.Float64).to_numpy())
    matrix = np.column_stack(cols)  # n x (4 * metrics)
    boot_sums = np.empty((resamples, matrix.shape[1]))
    done = 0
    while done < resamples:
        size = min(_CHUNK, resamples - done)
        counts = rng.multinomial(n, np.full(n, 1.0 / n), size=size).astype(np.float64)
        boot_sums[done : done + size] = counts @ matrix
        done += size
    totals = matrix.sum(axis=0)
    rows = []
    for i, m in enumerate(chosen):
        j = 4 * i
        a_val = _pooled(totals[j], totals[j + 1], m.scale)
        b_val = _pooled(totals[j + 2], totals[j + 3], m.scale)
        a_boot = _pooled(boot_sums[:, j], boot_sums[:, j + 1], m.scale)
        b_boot = _pooled(boot_sums[:, j + 2], boot_sums[:, j + 3], m.scale)
        diffs = b_boot - a_boot
        finite = diffs[np.isfinite(diffs)]
        a_v, b_v = _value(float(a_val)), _value(float(b_val))
        diff = b_v - a_v if a_v is not None and b_v is not None else None
        if diff is not None and finite.size:
            low, high = np.percentile(finite, [2.5, 97.5])
            ci_low, ci_high = float(low), float(high)
        else:
            ci_low = ci_high = None
        rows.append(
            {
                "metric": m.name,
                "direction": m.direction,
                "unit": m.unit,
                "A": a_v,
                "B": b_v,
                "diff": diff,
                "ci_low": ci_low,
                "ci_high": ci_high,
            }
        )
    metrics_df = pl.DataFrame(
        rows,
        schema={
            "metric": pl.String,
            "direction": pl.String,
            "unit": pl.String,
            "A": pl.Float64,
            "B": pl.Float64,
            "diff": pl.Float64,
            "ci_low": pl.Float64,
            "ci_high": pl.Float64,
        },
    )

    # ---- McNemar on success, and the flips
    paired = (
        a_eps.select("episode_id", "device_id", "category", pl.col("success").alias("a"))
        .join(b_eps.select("episode_id", pl.col("success").alias("b")), on="episode_id")
        .sort("episode_id")
    )
    both = int((paired["a"] & paired["b"]).sum())
    a_only = int((paired["a"] & ~paired["b"]).sum())
    b_only = int((~paired["a"] & paired["b"]).sum())
    neither = len(paired) - both - a_only - b_only
    mcnemar = pl.DataFrame(
        [
            {
                "n_common": len(paired),
                "both": both,
                "a_only": a_only,
                "b_only": b_only,
                "neither": neither,
                "p_value": mcnemar_exact(a_only, b_only),
            }
        ]
    )
    flips = (
        paired.filter(pl.col("a") != pl.col("b"))
        .with_columns(
            direction=pl.when(pl.col("a")).then(pl.lit("A_only")).otherwise(pl.lit("B_only"))
        )
        .select("episode_id", "device_id", "category", "direction")
        .sort("direction", "episode_id")
    )

    # ---- error distributions on the common episodes
    dist = error_distribution(
        store, by=("run_id",), where={"run_id": [run_a, run_b], "episode_id": common}
    )
    a_d = dist.filter(pl.col("run_id") == run_a).select(
        "error_group",
        "error_type",
        pl.col("count").alias("count_a"),
        pl.col("share").alias("share_a"),
    )
    b_d = dist.filter(pl.col("run_id") == run_b).select(
        "error_type", pl.col("count").alias("count_b"), pl.col("share").alias("share_b")
    )
    errors = (
        a_d.join(b_d, on="error_type", how="full", coalesce=True, maintain_order="left")
        .with_columns(
            label=pl.col("error_type").replace_strict(ERROR_LABELS),
            diff_pp=pl.col("share_b") - pl.col("share_a"),
        )
        .select(
            "error_group",
            "error_type",
            "label",
            "count_a",
            "count_b",
            "share_a",
            "share_b",
            "diff_pp",
        )
    )

    said = {r.run_id: r.complete for r in completeness(store, [run_a, run_b])}
    return Comparison(
        run_a=run_a,
        run_b=run_b,
        model_a=model_a,
        model_b=model_b,
        n_common=n,
        n_only_a=len(ids_a - ids_b),
        n_only_b=len(ids_b - ids_a),
        seed=seed,
        resamples=resamples,
        metrics=metrics_df,
        mcnemar=mcnemar,
        errors=errors,
        flips=flips,
        complete_a=said.get(run_a),
        complete_b=said.get(run_b),
    )


__all__ = ["DEFAULT_RESAMPLES", "DEFAULT_SEED", "Comparison", "compare", "mcnemar_exact"]
