"""Replay simulated runs and read their metrics from the platform's registry: the numbers used
to tune the profiles, to check them in tests and to report them in docs/SYNTHETIC.md.

No metric is computed here: the runs are replayed by `replay.replay_runs` into a temporary
OUT, and the values are the registry's (`vge_analytics.metrics`), the replay's counters and
the error taxonomy, exactly what `vge replay` then `vge metrics` print.
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import replay

from ..metrics import metrics
from ..reports import error_distribution, error_groups
from ..store import sql
from ._build import BENCH_DIR, RUNS_DIR


@dataclass(frozen=True, slots=True)
class RunMeasures:
    """One replayed run: its registry metrics (`metrics`, by name, None where a metric has no
    value, as the SQL says), counters and error mix."""

    run_id: str
    model: str
    episodes: int
    truncated_steps: int
    diverged_steps: int
    metrics: dict[str, float | None]
    terminations: dict[str, int] = field(default_factory=dict)
    error_shares: dict[str, float] = field(default_factory=dict)
    """Share of all errors (%) per error type."""
    error_groups: dict[str, float] = field(default_factory=dict)
    """Share of all errors (%) per group."""

    def __getattr__(self, name: str) -> float | None:
        """`m.sr`, `m.spl`, ...: the metric of that name (case-insensitive)."""
        for key, value in self.metrics.items():
            if key.lower().replace("-", "_") == name:
                return value
        raise AttributeError(name)


def measure_output(out_dir: Path, lam: float | None = None) -> dict[str, RunMeasures]:
    """Every run under `out_dir/runs`, replayed against `out_dir/bench` (λ by the replay's
    rule unless `lam` is given), by run id."""
    runs = sorted(p for p in (Path(out_dir) / RUNS_DIR).iterdir() if p.is_dir())
    with tempfile.TemporaryDirectory(prefix="vge-measure-") as tmp:
        replay.replay_runs(runs, Path(out_dir) / BENCH_DIR, tmp, lam=lam, progress=False)
        return _measures(Path(tmp))


def _measures(out: Path) -> dict[str, RunMeasures]:
    values = metrics(out, by=["run_id"]).rows(named=True)
    counts = {
        r["run_id"]: r
        for r in sql(
            out,
            "SELECT run_id, any_value(model) AS model, count(*) AS episodes, "
            "sum(truncated_steps) AS truncated_steps, sum(diverged_steps) AS diverged_steps, "
            "list(termination) AS terminations FROM episodes GROUP BY run_id",
        ).rows(named=True)
    }
    shares = _by_run(error_distribution(out, by="run_id").rows(named=True), "error_type")
    groups = _by_run(error_groups(out, by="run_id").rows(named=True), "error_group")
    found = {}
    for row in values:
        run_id = row.pop("run_id")
        row.pop("model", None)
        c = counts[run_id]
        ended: dict[str, int] = {}
        for termination in c["terminations"]:
            ended[termination] = ended.get(termination, 0) + 1
        found[run_id] = RunMeasures(
            run_id=run_id,
            model=c["model"],
            episodes=c["episodes"],
            truncated_steps=c["truncated_steps"],
            diverged_steps=c["diverged_steps"],
            metrics=row,
            terminations=dict(sorted(ended.items())),
            error_shares=shares.get(run_id, {}),
            error_groups=groups.get(run_id, {}),
        )
    return found


def _by_run(rows: list[dict], key: str) -> dict[str, dict[str, float]]:
    out: dict[str, dict[str, float]] = {}
    for r in rows:
        out.setdefault(r["run_id"], {})[r[key]] = r["share"]
    return out


__all__ = ["RunMeasures", "measure_output"]
