"""Repeated runs (`vge passk`) worked by hand on the 3 x 2 case: B and its two seeds."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

import replay
import vge_analytics as va
from vge_analytics.live._header import TOTAL_KEYS
from vge_analytics.reports import repeated
from vge_analytics.reports.inference import RUN_TOTALS


def test_pass_at_k_worked_by_hand(clustered_out: Path) -> None:
    """Successes of B, B-seed1, B-seed2 on e1..e6: (1,1,0), (1,0,1), (0,0,0), (1,1,1),
    (1,0,1), (1,1,0): c = 2, 2, 0, 3, 2, 2 of n = 3.
    pass@1 = 11/18; pass@2 = 1 - C(3-c, 2)/3: 1 for c >= 2, 0 for c = 0: 5/6; pass@3 = 5/6.
    pass^2 = C(c, 2)/3: 1/3, 1/3, 0, 1, 1/3, 1/3: 7/18; pass^3: only e4: 1/6.
    SR per run: 5/6, 3/6, 3/6: mean 11/18, SD (100/6) * sqrt(((4/3)^2 + 2 (2/3)^2) / 2)."""
    result = repeated(clustered_out)
    groups = {r["group"]: r for r in result.groups.iter_rows(named=True)}
    b = groups["B"]
    assert (b["runs"], b["n_runs"], b["n_episodes"], b["n_clusters"]) == (
        "B,B-seed1,B-seed2",
        3,
        6,
        3,
    )
    assert b["SR_mean"] == pytest.approx(1100 / 18)
    assert b["SR_sd"] == pytest.approx(100 / 6 * math.sqrt((16 / 9 + 8 / 9) / 2))
    assert b["ci_low"] <= b["SR_mean"] <= b["ci_high"] and b["note"] is None
    curve = result.passk.filter(result.passk["group"] == "B")
    assert curve["k"].to_list() == [1, 2, 3]
    assert curve["pass_at_k"].to_list() == pytest.approx([1100 / 18, 500 / 6, 500 / 6])
    assert curve["pass_hat_k"].to_list() == pytest.approx([1100 / 18, 700 / 18, 100 / 6])
    outcomes = result.outcomes.filter(result.outcomes["group"] == "B")
    assert outcomes["episodes"].to_list() == [1, 0, 4, 1]  # c = 0, 1, 2, 3
    episodes = result.sections(per_episode=True)["episodes"]
    assert episodes.filter(episodes["group"] == "B")["c"].to_list() == [2, 2, 0, 3, 2, 2]


def test_a_group_of_one_run_and_k_above_n_are_stated(clustered_out: Path) -> None:
    result = repeated(clustered_out, k=4)
    a = result.groups.filter(result.groups["group"] == "A").row(0, named=True)
    assert a["n_runs"] == 1 and a["SR_sd"] is None and a["SR_mean"] == pytest.approx(50.0)
    assert a["note"].startswith("one run: no spread between seeds")
    rows = result.passk.filter(result.passk["group"] == "A")
    assert rows["k"].to_list() == [1, 2, 3, 4]
    assert rows["pass_at_k"][0] == pytest.approx(50.0) and rows["pass_at_k"][1] is None
    assert rows["note"][1] == "k > n = 1 runs: not estimable"
    b4 = result.passk.filter((result.passk["group"] == "B") & (result.passk["k"] == 4))
    assert b4["note"][0] == "k > n = 3 runs: not estimable"


def test_grouping_by_columns_and_choosing_runs(clustered_out: Path) -> None:
    by_model = repeated(clustered_out, group_by=["model"])
    assert by_model.groups["runs"].to_list() == ["A", "B,B-seed1,B-seed2"]
    # B (1,1,0,1,1,1) and B-seed2 (0,1,0,1,1,0): c = 1, 2, 0, 2, 2, 1 of 2; pass^1 = 8/12,
    # pass^2 = C(c, 2) = 1 on e2, e4, e5: 3/6
    two = repeated(clustered_out, runs=["B", "B-seed2"])
    assert two.groups["runs"].to_list() == ["B,B-seed2"]
    assert two.passk["pass_hat_k"].to_list() == pytest.approx([800 / 12, 50.0])
    with pytest.raises(va.UnknownColumnError, match="--group-by 'nope'"):
        repeated(clustered_out, group_by=["nope"])
    with pytest.raises(va.AnalyticsError, match="k must be between 1 and 1000, not 0"):
        repeated(clustered_out, k=0)


def test_seeds_of_a_live_run_differ_only_in_keys_left_out() -> None:
    """The totals a group ignores are the ones `vge run` writes: one list, in replay.semantics
    (the protocol's names), not a copy in each room."""
    assert RUN_TOTALS is TOTAL_KEYS is replay.semantics.RUN_TOTALS
    assert "source_lines_unread" in RUN_TOTALS
