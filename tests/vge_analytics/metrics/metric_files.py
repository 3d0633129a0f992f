"""Metric files for the tests of metrics folders (`--metrics-dir`): text in the public format
(docs/METRICS.md), and a writer of folders made of them."""

from __future__ import annotations

from pathlib import Path


def metric_text(
    name: str,
    numerator: str,
    denominator: str,
    *,
    grain: str = "episodes",
    direction: str = "higher",
    unit: str = "percent",
    title: str | None = None,
    version: int = 1,
    definition: str = "A metric written for the tests.",
) -> str:
    """A metric file with every required header line."""
    return (
        f"-- metric: {name}\n"
        f"-- title: {title or name}\n"
        f"-- direction: {direction}\n"
        f"-- unit: {unit}\n"
        f"-- grain: {grain}\n"
        f"-- version: {version}\n"
        f"-- definition: {definition}\n"
        "\n"
        "-- numerator\n"
        f"{numerator}\n"
        "\n"
        "-- denominator\n"
        f"{denominator}\n"
    )


EXAMPLES = Path(__file__).resolve().parents[3] / "docs" / "examples" / "metrics"
"""The metrics folder docs/METRICS.md works through (SR-multi, TIR-dashboard, PSR)."""

SR_MULTI = (EXAMPLES / "sr_multi.sql").read_text(encoding="utf-8")
"""SR over the episodes with more than one goal (episodes grain; docs/examples/metrics)."""

TIR_DASHBOARD = (EXAMPLES / "tir_dashboard.sql").read_text(encoding="utf-8")
"""TIR over the interactions in the dashboard view (steps grain; docs/examples/metrics)."""

GOALS_DONE = metric_text(
    "GoalsDone",
    "count(*) FILTER (WHERE completed)",
    "count(*)",
    grain="goals",
    title="Goals completed",
    definition="Completed goals over all goals, in percent.",
)
"""The share of goals completed (goals grain)."""

SR_AS_SSR = metric_text(
    "SR",
    "sum(CAST(goals_completed AS DOUBLE) / n_goals)  -- partial credit per goal",
    "count(*)",
    title="Success Rate with partial credit",
    version=2,
    definition="SR that credits each completed goal: the mean of goals_completed / n_goals.",
)
"""An override of SR: SSR's definition under SR's name."""


RUNAWAY = """\
-- metric: Runaway
-- title: A metric whose expression never ends
-- direction: higher
-- unit: percent
-- level: episode-mean
-- grain: episodes
-- version: 1
-- definition: Counts a trillion numbers before it counts the episodes.
-- null: never null.

-- numerator
count(*) FILTER (WHERE (SELECT count(*) FROM range(1000000000000) AS t(i) WHERE i % 7 = 3) > 0)

-- denominator
count(*)
"""
"""A metric whose query runs until a time limit stops it (a scalar subquery over a trillion rows)."""


def write_folder(root: Path, files: dict[str, str]) -> Path:
    """A metrics folder at `root` holding `files` ({file name: text})."""
    root.mkdir(parents=True, exist_ok=True)
    for name, text in files.items():
        (root / name).write_text(text, encoding="utf-8")
    return root
