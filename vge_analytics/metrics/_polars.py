"""The metrics of PROTOCOL §6 again, written in polars, as an independent check of the DuckDB SQL.

Same inputs (the Parquet files of OUT, read directly), same definitions, written a second
time from PROTOCOL §6 without going through the registry's SQL; `test_polars_agrees` checks that
both give the same numbers (to 1e-9) on the hand-worked runs and on the bundled sample.
Grouping supports the columns of runs and episodes (the default: run_id, model).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import polars as pl

from replay.io import EPISODES_TABLE, GOALS_TABLE, RUNS_TABLE, STEPS_TABLE
from replay.semantics import SWITCH_VIEW

from .._errors import OutputDirError, UnknownColumnError
from ..store import GroupBy, parse_by
from ._registry import METRIC_NAMES, resolve_metrics

_EPISODE_METRICS = ("SR", "SSR", "SPL", "State-F1", "VSPS", "GVPE")
_STEP_METRICS = ("EIR", "TIR", "EER", "AvgDist", "AvgWDist")
_GOAL_METRICS = ("PSR",)


def _scan(out: Path, table: str) -> pl.LazyFrame:
    root = out / table
    files = sorted(str(p) for p in root.rglob("*.parquet"))
    if not files:
        raise OutputDirError(f"{root}: no Parquet files")
    # glob=False: each path is a file, whatever characters OUT's name holds (`out[12]`).
    return pl.scan_parquet(files, hive_partitioning=False, missing_columns="insert", glob=False)


def _ratio(num: pl.Expr, den: pl.Expr, scale: float) -> pl.Expr:
    return pl.when(den > 0).then(scale * num.cast(pl.Float64) / den).otherwise(None)


def _episode_aggs() -> dict[str, pl.Expr]:
    success = pl.col("success")
    l_opt = pl.col("L_opt").cast(pl.Float64)
    l_act = pl.col("L_act").cast(pl.Float64)
    spl = (
        pl.when(~success)
        .then(0.0)
        .when(pl.col("L_opt") == 0)
        .then(1.0)
        .otherwise(l_opt / pl.max_horizontal(l_act, l_opt))
    )
    visited = pl.col("visited_states").list.unique()
    optimal = pl.col("optimal_states").list.unique()
    f1 = (
        2.0
        * visited.list.set_intersection(optimal).list.len().cast(pl.Float64)
        / (visited.list.len() + optimal.list.len()).cast(pl.Float64)
    )
    done = pl.col("goals_completed")
    n = pl.len()
    return {
        "SR": _ratio(success.cast(pl.Int64).sum(), n, 100.0),
        "SSR": _ratio((done.cast(pl.Float64) / pl.col("n_goals")).sum(), n, 100.0),
        "SPL": _ratio(spl.sum(), n, 100.0),
        "State-F1": _ratio(f1.sum(), n, 100.0),
        "VSPS": _ratio(
            (pl.col("vsps_switches").cast(pl.Float64) / done).filter(done > 0).sum(),
            (done > 0).sum(),
            1.0,
        ),
        "GVPE": _ratio(pl.col("n_switches").sum(), done.sum(), 1.0),
    }


def _step_aggs() -> dict[str, pl.Expr]:
    inter = pl.col("is_interaction").fill_null(False)
    has_dist = pl.col("distance").is_not_null()
    non_switch = pl.col("action_type").is_null() | (pl.col("action_type") != SWITCH_VIEW)
    return {
        "EIR": _ratio((inter & pl.col("hit_component")).sum(), inter.sum(), 100.0),
        "TIR": _ratio((inter & pl.col("hit_target")).sum(), inter.sum(), 100.0),
        "EER": _ratio(pl.col("eer_valid").fill_null(False).sum(), non_switch.sum(), 100.0),
        "AvgDist": _ratio(pl.col("distance").filter(has_dist).sum(), has_dist.sum(), 1.0),
        "AvgWDist": _ratio(
            (pl.col("weight") * pl.col("distance")).filter(has_dist).sum(), has_dist.sum(), 1.0
        ),
    }


def _goal_aggs() -> dict[str, pl.Expr]:
    perfect = (
        pl.col("completed")
        & pl.col("c_opt_dyn").is_not_null()
        & (pl.col("steps_used") <= pl.col("c_opt_dyn"))
    )
    return {"PSR": _ratio(perfect.fill_null(False).sum(), pl.len(), 100.0)}


def polars_metrics(
    out: str | Path,
    by: GroupBy = None,
    metrics: str | Sequence[str] | None = None,
) -> pl.DataFrame:
    """PROTOCOL §6 metrics per group computed with polars (same columns as `metrics`)."""
    out = Path(out).resolve()
    names = [m.name for m in resolve_metrics(metrics)]
    by_cols = list(parse_by(by))
    episodes = _scan(out, EPISODES_TABLE)
    runs = _scan(out, RUNS_TABLE)
    ep_cols = set(episodes.collect_schema().names())
    run_cols = set(runs.collect_schema().names())
    for col in by_cols:
        if col not in ep_cols and col not in run_cols:
            raise UnknownColumnError(f"polars metrics group by runs/episodes columns, not {col!r}")
    run_only = [c for c in by_cols if c not in ep_cols]
    key_cols = list(dict.fromkeys(["run_id", "episode_id", *by_cols]))
    ep_keys = episodes.select([c for c in key_cols if c in ep_cols])
    if run_only:
        ep_keys = ep_keys.join(runs.select("run_id", *run_only), on="run_id", how="left")
        episodes = episodes.join(runs.select("run_id", *run_only), on="run_id", how="left")
    ep_keys = ep_keys.select(key_cols)

    parts: list[pl.DataFrame] = []
    plan = (
        (episodes, _episode_aggs(), _EPISODE_METRICS),
        (_scan(out, STEPS_TABLE).filter(~pl.col("truncated")), _step_aggs(), _STEP_METRICS),
        (_scan(out, GOALS_TABLE), _goal_aggs(), _GOAL_METRICS),
    )
    for frame, aggs, group in plan:
        wanted = [n for n in names if n in group]
        if not wanted:
            continue
        if frame is not episodes:
            drop = [c for c in by_cols if c not in ("run_id", "episode_id")]
            frame = frame.select(pl.exclude(drop)).join(
                ep_keys, on=["run_id", "episode_id"], how="inner"
            )
        exprs = [aggs[n].alias(n) for n in wanted]
        if by_cols:
            parts.append(frame.group_by(by_cols).agg(exprs).collect())
        else:
            parts.append(frame.select(exprs).collect())

    if not by_cols:
        result = pl.concat(parts, how="horizontal")
    else:
        if all(c in run_cols for c in by_cols):
            keys = runs.select(by_cols).unique().collect()
        else:
            keys = pl.concat([p.select(by_cols) for p in parts]).unique()
        result = keys
        for p in parts:
            result = result.join(p, on=by_cols, how="left", nulls_equal=True)
        result = result.sort(by_cols, nulls_last=True)
    order = [*by_cols, *[n for n in METRIC_NAMES if n in names]]
    return result.select(order).with_columns(pl.col(n).cast(pl.Float64) for n in names)


__all__ = ["polars_metrics"]
