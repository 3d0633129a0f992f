"""Metrics that users define, worked out by hand on the hand-worked runs (see
test_metrics_hand.py for the runs and the per-episode facts used here).

SR over multi-goal episodes (episodes grain). Kettle: the episodes with more than one goal
are a (2 goals, success), c (3, success), d (2, fails), e (2, fails), f (2, success): 3 of 5
= 60 %. Oven: a, c, d (2 goals each) all succeed: 100 %. The one-goal episodes (kettle b, g;
oven b, e) do not count.

TIR on the dashboard view (steps grain): only the oven has a dashboard view. Its interactions
made in the dashboard view (the view before the step): a step 7 (target), b steps 7, 8 (both
targets), c step 4 (target), d steps 5 (miss), 6, 7 (targets): 6 of 7 = 85.714...%. The kettle
run has no such interaction: null, not 0.

Goals completed (goals grain): kettle 2 + 0 + 3 + 1 + 1 + 2 + 1 = 10 of 13 goals; oven 8 of 8.

An override of SR by SSR's definition gives SSR's values under SR's name: kettle 5/7, oven 1.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import polars as pl
import pytest

import vge_analytics as va
from replay import ConfigError
from vge_analytics.cli import main

from .metric_files import (
    EXAMPLES,
    GOALS_DONE,
    RUNAWAY,
    SR_AS_SSR,
    SR_MULTI,
    TIR_DASHBOARD,
    write_folder,
)
from .test_metrics_hand import EXPECTED

HAND_VALUES = {
    "kettle-vlm": {"SR-multi": 60.0, "TIR-dashboard": None, "GoalsDone": 100 * 10 / 13},
    "oven-human": {"SR-multi": 100.0, "TIR-dashboard": 100 * 6 / 7, "GoalsDone": 100.0},
}


@pytest.fixture
def mine(tmp_path) -> Path:
    return write_folder(
        tmp_path / "mine",
        {
            "sr.sql": SR_AS_SSR,
            "sr_multi.sql": SR_MULTI,
            "tir_dashboard.sql": TIR_DASHBOARD,
            "goals_done.sql": GOALS_DONE,
        },
    )


def _close(got: float | None, want: float | None) -> bool:
    if want is None:
        return got is None
    return got is not None and math.isclose(got, want, rel_tol=0.0, abs_tol=1e-9)


def test_user_metrics_equal_the_hand_values(hand_out: Path, mine: Path) -> None:
    df = va.metrics(hand_out, metrics_dir=mine)
    # Built-ins in their order (SR overridden in place), then the added ones by name.
    assert df.columns == [
        "run_id",
        "model",
        *va.METRIC_NAMES,
        "GoalsDone",
        "SR-multi",
        "TIR-dashboard",
    ]
    for row in df.iter_rows(named=True):
        for name, want in HAND_VALUES[row["run_id"]].items():
            assert _close(row[name], want), (row["run_id"], name, row[name], want)
        # the override: SSR's definition under SR's name; the other built-ins unchanged
        assert _close(row["SR"], EXPECTED[row["run_id"]]["SSR"])
        assert _close(row["SSR"], EXPECTED[row["run_id"]]["SSR"])
        assert _close(row["EIR"], EXPECTED[row["run_id"]]["EIR"])


def test_the_documented_examples(hand_out: Path, sample_out: Path) -> None:
    # docs/examples/metrics: SR-multi and TIR-dashboard (above), and PSR over the goals
    # reached. Every goal of the hand runs became current (an episode stops at the goal it
    # fails, its last), so there the corrected PSR equals the built-in one: 5/13 and 3/8.
    examples = va.load_metrics(EXAMPLES)
    assert examples.names == (
        *va.METRIC_NAMES, *va.CONTINUATION_METRICS, "SR-multi", "TIR-dashboard",
    )  # fmt: skip
    changed = {
        m.name: examples.origin(m.name) for m in examples if examples.origin(m.name) != "built-in"
    }
    assert changed == {"PSR": "override", "SR-multi": "added", "TIR-dashboard": "added"}
    df = va.metrics(hand_out, metrics=["SR-multi", "TIR-dashboard", "PSR"], metrics_dir=EXAMPLES)
    for row in df.iter_rows(named=True):
        for name in ("SR-multi", "TIR-dashboard"):
            assert _close(row[name], HAND_VALUES[row["run_id"]][name])
        assert _close(row["PSR"], EXPECTED[row["run_id"]]["PSR"])
    # On the bundled sample, episodes stop before their later goals: the corrected PSR is
    # higher for every run (fewer goals in the denominator, the same perfect ones above it).
    before = va.metrics(sample_out, metrics="PSR")["PSR"].to_list()
    after = va.metrics(sample_out, metrics="PSR", metrics_dir=EXAMPLES)["PSR"].to_list()
    assert all(a > b for a, b in zip(after, before, strict=True) if b)


def test_grouping_applies_to_user_metrics(hand_out: Path, mine: Path) -> None:
    # TIR-dashboard by n_goals: oven 1-goal episodes b (2 of 2 in the dashboard view) and e
    # (none there): 100 %; 2-goal episodes a (1 of 1), c (1 of 1), d (2 of 3): 4 of 5 = 80 %.
    df = va.metrics(
        hand_out,
        by=["run_id", "n_goals"],
        metrics=["TIR-dashboard", "SR-multi"],
        metrics_dir=mine,
    )
    values = {(r, n): (t, s) for r, n, t, s in df.iter_rows()}
    assert values[("oven-human", 1)] == (100.0, None)  # no multi-goal episode: null
    assert _close(values[("oven-human", 2)][0], 80.0)
    assert values[("kettle-vlm", 3)] == (None, 100.0)  # c, the 3-goal episode, succeeds
    assert _close(values[("kettle-vlm", 2)][1], 50.0)  # a, f succeed; d, e fail
    # A steps-only column groups the steps metric, as for the built-ins.
    by_action = va.metrics(hand_out, by="action_type", metrics="TIR-dashboard", metrics_dir=mine)
    assert "press" in by_action["action_type"].to_list()
    with pytest.raises(va.UnknownColumnError, match="TIR-dashboard.*not.*SR-multi"):
        va.metrics(hand_out, by="action_type", metrics="TIR-dashboard,SR-multi", metrics_dir=mine)


def test_episode_terms_and_compare_use_the_folder(hand_out: Path, mine: Path, pair_out) -> None:
    terms = va.episode_terms(hand_out, ["SR-multi"], metrics_dir=mine)
    kettle = terms.filter(pl.col("run_id") == "kettle-vlm")
    assert (kettle["SR-multi:num"].sum(), kettle["SR-multi:den"].sum()) == (3, 5)
    cmp = va.compare(pair_out, "A", "B", metrics=["SR", "SR-multi"], metrics_dir=mine)
    assert cmp.metrics["metric"].to_list() == ["SR", "SR-multi"]
    builtin = va.compare(pair_out, "A", "B", metrics=["SSR"])
    assert cmp.metrics["A"][0] == pytest.approx(builtin.metrics["A"][0])  # SR is SSR's now


def test_vge_metrics_with_a_folder(capsys, hand_out: Path, mine: Path) -> None:
    code = main(["metrics", str(hand_out), "--metrics-dir", str(mine), "-f", "json"])
    assert code == 0
    rows = json.loads(capsys.readouterr().out)
    assert rows[0]["SR"] == 100 * 5 / 7 and rows[0]["SR-multi"] == 60.0
    assert rows[0]["TIR-dashboard"] is None
    code = main(
        ["metrics", str(hand_out), "--metrics-dir", str(mine), "--metrics", "SR,GoalsDone",
         "--by", "n_goals", "-f", "markdown"]
    )  # fmt: skip
    out = capsys.readouterr().out
    # Added metrics get their arrows and the best/second-best marks like the built-ins.
    assert code == 0 and "| n_goals | SR \u2191 | GoalsDone \u2191 |" in out
    assert "**100.00**" in out and "<u>" in out
    code = main(["metrics", str(hand_out), "--metrics", "SR-multi"])
    assert code == 1 and "unknown metric 'SR-multi'" in capsys.readouterr().err


def test_list_names_the_files(capsys, mine: Path) -> None:
    assert main(["metrics", "--list", "--metrics-dir", str(mine), "-f", "json"]) == 0
    rows = {r["metric"]: r for r in json.loads(capsys.readouterr().out)}
    assert list(next(iter(rows.values()))) == [
        "metric",
        "title",
        "version",
        "direction",
        "unit",
        "grain",
        "source",
        "definition",
    ]
    assert rows["SR"]["source"] == f"{mine}/sr.sql" and rows["SR"]["version"] == 2
    assert rows["SR"]["title"] == "Success Rate with partial credit"
    assert rows["SSR"]["source"] == "built-in"
    assert rows["TIR-dashboard"]["source"] == f"{mine}/tir_dashboard.sql"
    assert rows["TIR-dashboard"]["grain"] == "steps"
    assert list(rows)[-3:] == ["GoalsDone", "SR-multi", "TIR-dashboard"]
    assert main(["metrics", "--list"]) == 0
    out = capsys.readouterr().out
    assert "built-in" in out and "Success Rate" in out
    assert main(["metrics"]) == 2  # OUT is needed unless --list
    assert "Missing argument 'OUT'" in capsys.readouterr().err


def test_metric_set_origins(mine: Path) -> None:
    chosen = va.load_metrics(mine)
    assert chosen.origin("SR") == "override" and chosen.origin("SSR") == "built-in"
    assert chosen.origin("SR-multi") == "added"
    table = va.metric_table(mine)
    assert table.filter(pl.col("metric") == "SR")["origin"].to_list() == ["override"]
    assert chosen.fingerprint != va.MetricSet.builtin().fingerprint
    with pytest.raises(va.UnknownMetricError, match="did you mean SR-multi"):
        chosen.get("sr-multi")


def test_a_metric_named_like_a_grouping_column(hand_out: Path, tmp_path: Path) -> None:
    folder = write_folder(
        tmp_path / "clash",
        {"model.sql": SR_MULTI.replace("-- metric: SR-multi", "-- metric: model")},
    )
    with pytest.raises(va.UnknownColumnError, match="'model' has the name of a grouping column"):
        va.metrics(hand_out, metrics_dir=folder)
    assert va.metrics(hand_out, by="run_id", metrics_dir=folder)["model"].to_list() == [60.0, 100.0]


def test_sweep_uses_the_folder(hand, mine: Path) -> None:
    # The sweep's SR is the folder's SR: SSR's definition, at every lambda.
    df = va.sweep(hand["out"], [2, 5], metrics=["SR", "SSR", "SR-multi"], metrics_dir=mine)
    assert df["SR"].to_list() == df["SSR"].to_list()
    # SR-multi, by hand from the case files' notes (PROTOCOL §3.5: B_global = λ·L_opt,
    # B_local from λ·C_opt of the current goal, refilled on completion; success first).
    # Kettle, multi-goal a, c, d, e, f. At λ 2 only c (its own λ) succeeds: a runs out of
    # B_local = 4 at step 3, d of 4 at step 3, f of B_global = 4 at step 3, e's log ends.
    # At λ 5: a (its own λ), c, f, and d, whose Timed_wait at step 6 (truncated at λ 3)
    # reaches Standby with B_local 3 left; e's log still ends first: 4 of 5.
    # Oven, multi-goal a, c, d. At λ 2 each runs out of B_local (a at step 4, c and d at
    # step 1). At λ 5 a (its own λ) and c (goal 1 at step 2, B_local refilled to 10)
    # succeed; d spends B_local = 5 before its goal 1 at step 6 (it needed λ 8): 2 of 3.
    assert df.select("run_id", "lambda", "SR-multi").rows() == [
        ("kettle-vlm", 2.0, 20.0),
        ("kettle-vlm", 5.0, 80.0),
        ("oven-human", 2.0, 0.0),
        ("oven-human", 5.0, pytest.approx(100 * 2 / 3)),
    ]
    builtin = va.sweep(hand["out"], [2, 5], metrics=["SR"])
    assert builtin["SR"].to_list() != df["SR"].to_list()
    with pytest.raises(ConfigError, match="episode metrics: SR, SSR, .*SR-multi"):
        va.sweep(hand["out"], [5], metrics=["TIR-dashboard"], metrics_dir=mine)


def test_builtin_values_do_not_change_without_a_folder(hand_out: Path) -> None:
    # The polars cross-check (test_polars_agrees.py) covers the built-ins; with no folder and
    # no environment variable, metrics are the built-ins exactly.
    assert va.metrics(hand_out).equals(va.metrics(hand_out, metrics_dir=va.MetricSet.builtin()))


def test_a_runaway_metric_stops_at_the_time_limit(
    capsys, hand_out: Path, pair_out: Path, tmp_path: Path
) -> None:
    folder = write_folder(tmp_path / "runaway", {"runaway.sql": RUNAWAY})
    # The API has no limit unless asked; within the block, the query stops at it.
    with va.query_time_limit(0.5), pytest.raises(va.QueryLimitError) as caught:
        va.metrics(hand_out, metrics=["SR", "Runaway"], metrics_dir=folder)
    assert caught.value.limit == "time"
    # The line names the metric file whose SQL the stopped query holds.
    named = f"{folder / 'runaway.sql'}: the query of this metric file"
    assert str(caught.value) == f"{named} ran past its time limit of 0.5 s and was stopped"
    # The limit ends with the block: the built-ins are computed as before.
    assert va.metrics(hand_out, metrics=["SR"])["SR"].to_list() == [
        EXPECTED[run]["SR"] for run in ("kettle-vlm", "oven-human")
    ]
    # The commands take --timeout; the error is one line.
    for args in (
        ["metrics", str(hand_out), "--metrics", "Runaway"],
        ["compare", str(pair_out), "A", "B"],
        ["rescore", str(hand_out)],
    ):
        code = main([*args, "--metrics-dir", str(folder), "--timeout", "0.5"])
        err = capsys.readouterr().err
        assert code == 1, (args[0], err)
        assert err == (
            f"error: {named} ran past its time limit of 0.5 s and was stopped "
            "(--timeout sets the limit)\n"
        ), args[0]
    # Queries that end in time are not affected by one.
    assert main(["errors", str(hand_out), "--timeout", "0.5"]) == 0
