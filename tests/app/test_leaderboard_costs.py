"""The leaderboard's cost and completeness (vge_analytics.dashboard): cost per episode and per
success, the cost–success frontier, the incomplete runs marked. Worked by hand on four runs of
the two-task kettle benchmark, priced at $1 per million prompt tokens:

| run | open-lid | boil | SR | cost | $ / episode | $ / success |
|---|---|---|---:|---:|---:|---:|
| a | success, 1000 tokens | success, 2 x 1000 | 100 | 0.003 | 0.0015 | 0.0015 |
| b | fails, 4000 | success, 2 x 2000 | 50 | 0.008 | 0.004 | 0.008 |
| c | success, no tokens | fails, none | 50 | null | null | null |
| d | fails, 500 | fails, 500 | 0 | 0.001 | 0.0005 | null |

Frontier (lower cost per episode, higher SR): d (cheapest) and a (nothing costs less and
succeeds more); b is dominated by a. c has no cost: not on the plane. d's run.json says
`complete: false` with 2 infrastructure failures."""

from __future__ import annotations

import json
from pathlib import Path

import polars as pl
import pytest

import replay
import vge_analytics as va
from vge_analytics import dashboard as dash
from vge_analytics.reports import MISSING

from ..vge_analytics.live.conftest import MALFORMED, OPEN_LID, PUSH_POWER, WAIT, kettle_bench  # noqa: F401
from .test_pages import chart_data, charts, nums, open_page

RUNS = {
    "a": [[(OPEN_LID, 1000)], [(PUSH_POWER, 1000), (WAIT, 1000)]],
    "b": [[(MALFORMED, 4000)], [(PUSH_POWER, 2000), (WAIT, 2000)]],
    "c": [[(OPEN_LID, None)], [(MALFORMED, None)]],
    "d": [[(MALFORMED, 500)], [(MALFORMED, 500)]],
}


@pytest.fixture
def priced_out(kettle_bench: Path, tmp_path: Path) -> Path:  # noqa: F811
    dirs = []
    for run_id, episodes in RUNS.items():
        run = tmp_path / run_id
        run.mkdir()
        meta = {"prompt_price_per_mtok": 1.0} if run_id != "c" else {}
        if run_id == "d":
            meta |= {"complete": False, "infrastructure_failures": 2}
        header = {"run_id": run_id, "model": f"model-{run_id}", "agent_kind": "vlm", "meta": meta}
        (run / "run.json").write_text(json.dumps(header))
        lines = []
        for episode_id, steps in zip(("open-lid", "boil"), episodes, strict=True):
            logged = [
                {"output": text} | ({"prompt_tokens": n} if n is not None else {})
                for text, n in steps
            ]
            lines.append(json.dumps({"episode_id": episode_id, "steps": logged}))
        (run / "episodes.jsonl").write_text("\n".join(lines) + "\n")
        dirs.append(run)
    out = tmp_path / "out"
    replay.replay_runs(dirs, kettle_bench, out, progress=False)
    return out


def test_cost_per_episode_and_per_success(priced_out: Path) -> None:
    costs = dash.cost_table(priced_out, ["run_id", "model"])
    rows = {r["run_id"]: r for r in costs.to_dicts()}
    assert {k: (r["episodes"], r["successes"], r["SR"]) for k, r in rows.items()} == {
        "a": (2, 2, 100.0), "b": (2, 1, 50.0), "c": (2, 1, 50.0), "d": (2, 0, 0.0),
    }  # fmt: skip
    expected = {
        "a": (0.003, 0.0015, 0.0015),
        "b": (0.008, 0.004, 0.008),
        "c": (None, None, None),
        "d": (0.001, 0.0005, None),
    }
    for run_id, (total, per_episode, per_success) in expected.items():
        r = rows[run_id]
        assert (r["cost_usd"], r["cost_per_episode"], r["cost_per_success"]) == pytest.approx(
            (total, per_episode, per_success)
        ), run_id

    # Grouped by something else: the same sums, added up (the two-level aggregation).
    by_task = dash.cost_table(priced_out, ["agent_kind"], where={"run_id": ["a", "b"]})
    assert by_task.select("episodes", "successes").row(0) == (4, 3)
    assert by_task["cost_usd"][0] == pytest.approx(0.011)
    assert by_task["cost_per_success"][0] == pytest.approx(0.011 / 3)


def test_the_leaderboard_table_gets_the_costs_and_the_marks(priced_out: Path) -> None:
    by = ["run_id", "model"]
    table = va.metrics(priced_out, by=by, metrics=["SR"])
    joined = dash.with_costs(table, dash.cost_table(priced_out, by), by)
    assert joined.columns == ["run_id", "model", *dash.COST_COLUMNS, "SR"]  # costs in sight
    assert joined["cost_per_success"].to_list() == pytest.approx([0.0015, 0.008, None, None])
    # Without any recorded cost the table is left as it is.
    plain = table.filter(pl.col("run_id") == "c")
    only_c = dash.cost_table(priced_out, by, where={"run_id": ["c"]})
    assert dash.with_costs(plain, only_c, by).columns == ["run_id", "model", "SR"]

    runs = va.completeness(priced_out)
    incomplete = [r.run_id for r in runs if r.incomplete]
    assert incomplete == ["d"]
    labelled = table.with_columns(group=pl.col("run_id")).select("group", "SR")
    marked = dash.incomplete_groups(labelled, by, incomplete)
    assert marked["group"].to_list() == ["a", "b", "c", "d (incomplete)"]
    assert dash.incomplete_groups(labelled, ["model"], incomplete).equals(labelled)
    assert dash.incomplete_note(runs) == (
        "Incomplete: **d** (2 infrastructure failure(s)). Their run.json says "
        "`complete: false`: the metrics cover the episodes written so far, not the run's "
        "selection; `vge run --resume` completes it."
    )


def test_the_cost_success_frontier(priced_out: Path) -> None:
    plane = dash.cost_frontier(dash.cost_table(priced_out, ["run_id", "model"]))
    assert plane.to_dicts() == [
        {"run_id": "d", "SR": 0.0, "cost_per_episode": pytest.approx(0.0005), "frontier": True},
        {"run_id": "a", "SR": 100.0, "cost_per_episode": pytest.approx(0.0015), "frontier": True},
        {"run_id": "b", "SR": 50.0, "cost_per_episode": pytest.approx(0.004), "frontier": False},
    ]


def test_frontier_ties_and_dominance() -> None:
    """Equal points are both on the frontier; a point as cheap but less successful is not."""
    runs = pl.DataFrame(
        {
            "run_id": ["p", "q", "r", "s"],
            "SR": [60.0, 60.0, 40.0, 80.0],
            "cost_per_episode": [1.0, 1.0, 1.0, 3.0],
        }
    )
    plane = dash.cost_frontier(runs)
    assert list(zip(plane["run_id"], plane["frontier"], strict=True)) == [
        ("p", True), ("q", True), ("r", False), ("s", True),
    ]  # fmt: skip


def test_the_leaderboard_page_shows_costs_marks_and_the_frontier(
    priced_out: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("VGE_APP_OUT", str(priced_out))
    at = open_page()
    assert any("Incomplete: **d** (2 infrastructure failure(s))" in w.value for w in at.warning)
    shown = at.dataframe[0].value
    assert list(shown["group"]) == ["a", "b", "c", "d (incomplete)"]
    assert nums(shown["cost_per_episode"]) == pytest.approx(
        [0.0015, 0.004, float("nan"), 0.0005], nan_ok=True
    )
    assert nums(shown["cost_per_success"]) == pytest.approx(
        [0.0015, 0.008, float("nan"), float("nan")], nan_ok=True
    )
    # Missing values are drawn as `–`; the costs come after the labels; the group column
    # is as wide as its longest label and stays in place when the table scrolls sideways.
    assert at.dataframe[0].proto.placeholder == MISSING
    assert list(shown.columns[:4]) == ["group", "model", "cost_per_episode", "cost_per_success"]
    config = json.loads(at.dataframe[0].proto.columns)
    assert config["group"]["width"] == dash.text_width("group", "d (incomplete)") == 136
    assert config["group"]["pinned"] is True
    assert config["cost_per_episode"]["label"] == "$ / episode"
    frontier = chart_data(charts(at)[1])
    points = next(f for f in frontier if f.height == 3)
    assert list(zip(points["run_id"], points["frontier"], strict=True)) == [
        ("d", True), ("a", True), ("b", False),
    ]  # fmt: skip


def test_a_column_sized_to_its_text() -> None:
    # 8 px a character and 24 px of padding, at most 480 px.
    assert dash.text_width("group") == 5 * 8 + 24
    assert dash.text_width("a", "random-cut (incomplete)", "b") == 23 * 8 + 24
    assert dash.text_width("x" * 100_000) == 480  # a hostile run id gets no page-wide column
    assert dash.text_width() == 24
