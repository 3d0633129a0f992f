"""`vge rescore`: values, ranks and Kendall's tau-b before and after a metrics folder, worked
by hand on the hand-worked runs.

Grouped by run and goal count, the hand runs have five groups (kettle 1, 2, 3 goals; oven 1,
2 goals). SR per group (test_metrics_hand.py's facts): kettle 1 goal: b fails, g succeeds ->
50; kettle 2 goals: a, f succeed, d, e fail -> 50; kettle 3 goals: c -> 100; oven 1 and 2
goals: all succeed -> 100. Ranks (1 = best, ties share, "1224"): the three 100s rank 1, the
two 50s rank 4.

The folder overrides SR with SSR's definition (partial credit per goal): kettle 1 goal: b 0/1,
g 1/1 -> 50; kettle 2 goals: a 1, d 1/2, e 1/2, f 1 -> 75; kettle 3 goals: 100; oven: 100.
Ranks after: the 100s rank 1, kettle 2 goals 4, kettle 1 goal 5. Only kettle 1 goal moved
(4 -> 5).

Kendall's tau-b over the ten pairs of groups: the six pairs between a 100-group and a
kettle 1- or 2-goal group are ordered the same way before and after (concordant); kettle 1
vs 2 goals is tied before (50, 50) and ordered after: neither; the three pairs among the
100-groups are tied both times: neither. C = 6, D = 0; n0 = 10; ties before n1 = 1 (the two
50s) + 3 (the three 100s) = 4; ties after n2 = 3. tau-b = 6 / sqrt((10 - 4)(10 - 3)) =
6 / sqrt(42) = 0.9258...; tau-a would be 6/10, counting the ties against an unchanged order.
"""

from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path

import polars as pl
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import vge_analytics as va
from vge_analytics.cli import main
from vge_analytics.reports._ranking import kendall_tau_b_pairs

from ..metrics.metric_files import GOALS_DONE, SR_AS_SSR, SR_MULTI, metric_text, write_folder

TAU_BY_GOALS = 6 / math.sqrt(42)


@pytest.fixture
def mine(tmp_path) -> Path:
    return write_folder(tmp_path / "mine", {"sr.sql": SR_AS_SSR, "multi.sql": SR_MULTI})


def run(capsys, *args: str) -> tuple[int, str, str]:
    code = main([*args])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


# ------------------------------------------------------------------------------ ranking


def test_competition_ranks() -> None:
    assert va.competition_ranks([50.0, 100.0, 100.0, None, 75.0], True) == [4, 1, 1, None, 3]
    assert va.competition_ranks([0.7, 1.125, float("nan")], False) == [1, 2, None]
    # Equal at 9 decimals: a tie (float noise does not split a tie).
    assert va.competition_ranks([100 * 4 / 7, 400 / 7 + 1e-12, 10.0], True) == [1, 1, 3]
    assert va.competition_ranks([], True) == []


def test_kendall_tau_b_worked_by_hand() -> None:
    # x = ranks before, y = ranks after, five groups:
    #   x = 1, 2, 2, 4, 5;  y = 2, 1, 3, 3, 5
    # Pairs: (0,1) x up, y down: discordant. (1,2) tied in x; (2,3) tied in y: neither. The
    # seven others are ordered the same way by both: concordant. C = 7, D = 1, n0 = 10,
    # n1 = n2 = 1: tau-b = (7 - 1) / sqrt(9 * 9) = 2/3 (tau-a would be 6/10).
    x, y = [1, 2, 2, 4, 5], [2, 1, 3, 3, 5]
    assert va.kendall_tau_b(x, y) == pytest.approx(2 / 3, abs=1e-15)
    assert kendall_tau_b_pairs(x, y) == pytest.approx(2 / 3, abs=1e-15)
    assert va.kendall_tau_b([1, 2, 3], [3, 2, 1]) == -1.0
    assert va.kendall_tau_b([1, 1, 3], [1, 1, 3]) == 1.0  # ties agree: exactly 1 (tau-b)
    assert va.kendall_tau_b([1, 1], [1, 2]) is None  # one ranking ties everything
    assert va.kendall_tau_b([1], [1]) is None


@settings(max_examples=300, deadline=None)
@given(
    st.lists(st.tuples(st.integers(0, 6), st.integers(0, 6)), min_size=0, max_size=60)
)
def test_fast_tau_equals_the_pairwise_definition(pairs) -> None:
    x = [p[0] for p in pairs]
    y = [p[1] for p in pairs]
    fast, reference = va.kendall_tau_b(x, y), kendall_tau_b_pairs(x, y)
    assert (fast is None) == (reference is None)
    if fast is not None:
        assert fast == pytest.approx(reference, abs=1e-12)


# ------------------------------------------------------------------------------ rescore


def test_rescore_by_run_and_goal_count(hand_out: Path, mine: Path) -> None:
    result = va.rescore(hand_out, mine, by="run_id,n_goals")
    sr = result.rows.filter(pl.col("metric") == "SR")
    assert sr.columns == [
        "metric", "run_id", "n_goals", "before", "after", "delta", "rank_before", "rank_after",
    ]  # fmt: skip
    rows = {(r["run_id"], r["n_goals"]): r for r in sr.iter_rows(named=True)}
    expected = {
        # group: before, after, rank before, rank after
        ("kettle-vlm", 1): (50.0, 50.0, 4, 5),
        ("kettle-vlm", 2): (50.0, 75.0, 4, 4),
        ("kettle-vlm", 3): (100.0, 100.0, 1, 1),
        ("oven-human", 1): (100.0, 100.0, 1, 1),
        ("oven-human", 2): (100.0, 100.0, 1, 1),
    }
    for group, (before, after, rank_before, rank_after) in expected.items():
        row = rows[group]
        assert row["before"] == pytest.approx(before) and row["after"] == pytest.approx(after)
        assert row["delta"] == pytest.approx(after - before)
        assert (row["rank_before"], row["rank_after"]) == (rank_before, rank_after), group
    # by rank after, then rank before, then the groups
    assert sr["rank_after"].to_list() == [1, 1, 1, 4, 5]
    summary = result.summary.row(0, named=True)
    assert summary["metric"] == "SR" and summary["change"] == "changed"
    assert summary["source"] == f"{mine}/sr.sql" and summary["groups"] == 5
    assert summary["kendall_tau_b"] == pytest.approx(TAU_BY_GOALS, abs=1e-12)
    assert summary["moved"] == ["kettle-vlm · 1 4→5"]

    added = result.summary.row(1, named=True)
    assert (added["metric"], added["change"], added["kendall_tau_b"]) == ("SR-multi", "added", None)
    multi = result.rows.filter(pl.col("metric") == "SR-multi")
    assert multi["before"].null_count() == multi.height == 5
    assert multi["rank_before"].null_count() == 5
    # SR-multi: kettle 3 goals 100, oven 2 goals 100 (rank 1), kettle 2 goals 50 (rank 3),
    # the one-goal groups have no multi-goal episode: null, no rank.
    assert multi["rank_after"].to_list() == [1, 1, 3, None, None]


def test_rescore_per_run(hand_out: Path, mine: Path) -> None:
    result = va.rescore(hand_out, mine)
    assert result.by == ("run_id",)
    sr = result.rows.filter(pl.col("metric") == "SR")
    assert sr["run_id"].to_list() == ["oven-human", "kettle-vlm"]
    assert sr["before"].to_list() == pytest.approx([100.0, 100 * 4 / 7])
    assert sr["after"].to_list() == pytest.approx([100.0, 100 * 5 / 7])
    assert sr["delta"].to_list() == pytest.approx([0.0, 100 / 7])
    assert result.summary["kendall_tau_b"].to_list() == [1.0, None]
    assert result.summary["moved"].to_list() == [[], []]


def test_a_reversed_direction_reverses_the_ranking(hand_out: Path, tmp_path: Path) -> None:
    # AvgDist with "higher is better": kettle (109.84) and oven (29.55) swap: tau-b = -1.
    text = metric_text(
        "AvgDist", "sum(distance)", "count(distance)", grain="steps", unit="distance",
    )  # fmt: skip
    folder = write_folder(tmp_path / "flip", {"d.sql": text})
    result = va.rescore(hand_out, folder)
    assert result.rows["delta"].to_list() == [0.0, 0.0]
    assert result.summary.row(0, named=True)["kendall_tau_b"] == -1.0
    assert result.summary.row(0, named=True)["moved"] == ["kettle-vlm 2→1", "oven-human 1→2"]


def test_against_another_folder(hand_out: Path, tmp_path: Path) -> None:
    old = write_folder(tmp_path / "old", {"sr.sql": SR_AS_SSR, "goals.sql": GOALS_DONE})
    new = write_folder(tmp_path / "new", {"multi.sql": SR_MULTI})
    result = va.rescore(hand_out, new, against=old)
    assert result.summary.select("metric", "change").rows() == [
        ("SR", "changed"),  # the built-in SR again, against old's override
        ("SR-multi", "added"),
        ("GoalsDone", "removed"),
    ]
    sr = result.rows.filter(pl.col("metric") == "SR")
    assert sr["before"].to_list() == pytest.approx([100.0, 100 * 5 / 7])
    assert sr["after"].to_list() == pytest.approx([100.0, 100 * 4 / 7])
    removed = result.rows.filter(pl.col("metric") == "GoalsDone")
    assert removed["after"].null_count() == 2 and removed["rank_before"].to_list() == [1, 2]
    assert result.summary.row(2, named=True)["source"] == f"{old}/goals.sql"


def test_a_file_that_changes_no_value_is_not_reported(hand_out: Path, tmp_path: Path, capsys):
    # The built-in SR's SQL with another title and version: values and ranks cannot change.
    text = metric_text(
        "SR", "count(*) FILTER (WHERE success)", "count(*)", title="Renamed", version=9
    )
    folder = write_folder(tmp_path / "same", {"sr.sql": text})
    result = va.rescore(hand_out, folder)
    assert result.rows.height == 0 and result.summary.height == 0
    code, out, err = run(capsys, "rescore", str(hand_out), "--metrics-dir", str(folder), "-f", "json")
    assert code == 0 and json.loads(out) == []
    assert "changes no metric" in err


def test_rescore_needs_a_folder(hand_out: Path, capsys, monkeypatch) -> None:
    monkeypatch.delenv("VGE_METRICS_DIR", raising=False)
    code, _, err = run(capsys, "rescore", str(hand_out))
    assert code == 1 and err == (
        "error: rescore needs a metrics folder: --metrics-dir DIR (or $VGE_METRICS_DIR)\n"
    )


# --------------------------------------------------------------------------- the command


def test_json_is_a_list_of_objects(capsys, hand_out: Path, mine: Path) -> None:
    code, out, _ = run(capsys, "rescore", str(hand_out), "--metrics-dir", str(mine), "-f", "json")
    assert code == 0
    rows = json.loads(out)
    assert isinstance(rows, list) and len(rows) == 4
    for row in rows:
        assert list(row) == [
            "metric", "run_id", "before", "after", "delta", "rank_before", "rank_after",
        ]  # fmt: skip
    kettle = next(r for r in rows if r["metric"] == "SR" and r["run_id"] == "kettle-vlm")
    assert kettle["before"] == 100 * 4 / 7 and kettle["after"] == 100 * 5 / 7  # full precision
    assert kettle["delta"] == 100 * 5 / 7 - 100 * 4 / 7
    new = [r for r in rows if r["metric"] == "SR-multi"]
    assert all(r["before"] is None and r["rank_before"] is None for r in new)
    assert [r["after"] for r in new] == [100.0, 60.0]

    code, out, _ = run(
        capsys, "rescore", str(hand_out), "--metrics-dir", str(mine), "--by", "run_id,n_goals",
        "--summary", "-f", "json",
    )  # fmt: skip
    summary = json.loads(out)
    assert [list(r) for r in summary][0] == [
        "metric", "change", "source", "groups", "kendall_tau_b", "moved",
    ]  # fmt: skip
    assert summary[0]["kendall_tau_b"] == TAU_BY_GOALS and summary[0]["moved"] == [
        "kettle-vlm · 1 4→5"
    ]


def test_csv_and_the_formats_for_people(capsys, hand_out: Path, mine: Path) -> None:
    args = ["rescore", str(hand_out), "--metrics-dir", str(mine), "--by", "run_id,n_goals"]
    code, out, _ = run(capsys, *args, "-f", "csv")
    records = list(csv.DictReader(io.StringIO(out)))
    assert code == 0 and len(records) == 10
    assert list(records[0]) == [
        "metric", "run_id", "n_goals", "before", "after", "delta", "rank_before", "rank_after",
    ]  # fmt: skip
    code, out, _ = run(capsys, *args, "-f", "markdown")
    assert code == 0
    assert "### changes" in out and "### rankings" in out
    assert "| SR | kettle-vlm | 1 | 50.00 | 50.00 | 0.00 | 4 | 5 | ▼ 1 |" in out
    assert "| SR | changed | " in out and "| 5 | 0.93 | kettle-vlm · 1 4→5 |" in out
    assert "| SR-multi | kettle-vlm | 2 | – | 50.00 | – | – | 3 | new |" in out
    code, out, _ = run(capsys, *args)
    assert code == 0 and "kendall_tau_b" in out and "0.93" in out and "▼ 1" in out
    code, out, _ = run(capsys, *args, "-f", "latex")
    assert code == 0 and "\\toprule" in out and "kettle-vlm" in out


def test_bad_folder_stops_rescore(capsys, hand_out: Path, tmp_path: Path) -> None:
    folder = write_folder(tmp_path / "bad", {"x.sql": SR_MULTI.replace("higher", "upwards")})
    code, _, err = run(capsys, "rescore", str(hand_out), "--metrics-dir", str(folder))
    assert code == 1 and err.count("\n") == 1
    assert f"{folder}/x.sql:3: unknown direction 'upwards'" in err
    code, _, err = run(
        capsys, "rescore", str(hand_out), "--metrics-dir", str(tmp_path), "--against",
        str(tmp_path / "nowhere"),
    )  # fmt: skip
    assert code == 1


def test_some_metrics_and_step_groups(hand_out: Path, capsys) -> None:
    from ..metrics.metric_files import EXAMPLES

    # A steps-only column groups a steps metric: pick it with --metrics.
    result = va.rescore(hand_out, EXAMPLES, by="run_id,action_type", metrics="TIR-dashboard")
    assert result.summary["metric"].to_list() == ["TIR-dashboard"]
    ranked = result.rows.filter(pl.col("rank_after").is_not_null())
    # oven: the dashboard interactions are presses (a 7, b 8, c 4, d 5, d 6, d 7: all on a
    # target but d 5, 5 of 6) and one push (b 7, on a target).
    assert ranked.select("action_type", "after", "rank_after").rows() == [
        ("push", 100.0, 1),
        ("press", pytest.approx(100 * 5 / 6), 2),
    ]
    with pytest.raises(va.UnknownMetricError, match="does not change 'SR'; .*: PSR, SR-multi"):
        va.rescore(hand_out, EXAMPLES, metrics=["SR"])
    code, _, err = run(capsys, "rescore", str(hand_out), "--metrics-dir", str(EXAMPLES), "--by", "")
    assert code == 1 and "--by needs at least one column" in err
