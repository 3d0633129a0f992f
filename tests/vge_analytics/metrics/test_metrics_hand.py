"""Every PROTOCOL §6 metric equals the value worked out by hand on the hand-worked episodes.

The runs (see conftest): `kettle-vlm` = kettle cases a-g, `oven-human` = dashboard cases
a-e of `tests/data/hand_worked/`, replayed with `replay.replay_runs`. The per-step and
per-episode facts used below are the hand-worked `expected` values of those files (worked out
from the protocol, not by running the engine); the metric values are derived from them here, by
hand, with PROTOCOL §6:

Kettle run, per episode (S, goals done/n, L_opt, L_act, |V|, |O|, |V&O|, switches, vsps):
  a: S=1, 2/2, L_opt 3, L_act 10 -> SPL 3/10;  V {Standby LidOpen Boiling BoilingComplete},
     O {Standby Boiling BoilingComplete}: F1 = 2*3/(4+3) = 6/7; 3 switches (steps 1-3, while
     goal 1, completed, was current) -> VSPS 3/2.
  b: S=0, 0/1, L_opt 2, L_act 6 (2 truncated) -> SPL 0; V {Standby Boiling Error}, O {Standby
     Boiling BoilingComplete}: F1 = 2*2/6 = 2/3; 0 switches; no goal done -> not in VSPS.
  c: S=1, 3/3, L_opt 4, L_act 8 -> SPL 1/2; V = O (4 states) -> F1 1; 0 switches -> VSPS 0.
  d: S=0, 1/2, L_opt 3, L_act 6 -> SPL 0; V {Standby Boiling}, O 3 states: F1 = 4/5;
     switches: step 0 (goal 1, done) and step 3 (goal 2, not done) -> VSPS 1/1.
  e: S=0, 1/2, log_ended after 5 steps -> SPL 0; V {Standby LidOpen Error Boiling}, O 3:
     F1 = 2*2/7 = 4/7; switches: step 1 (goal 1, done), step 4 (goal 2) -> VSPS 1/1.
  f: S=1, 2/2, L_opt 2, L_act 5 -> SPL 2/5; V = O -> F1 1; 0 switches -> VSPS 0.
  g: S=1, 1/1, L_opt 1, L_act 1 -> SPL 1; F1 1; VSPS 0.
  SR  = 4/7 = 57.142857...%                SSR = (1+0+1+1/2+1/2+1+1)/7 = 5/7 = 71.428571...%
  SPL = (0.3+0+0.5+0+0+0.4+1)/7 = 2.2/7 = 31.428571...%
  State-F1 = (6/7+2/3+1+4/5+4/7+1+1)/7 = (619/105)/7 = 619/735 = 84.217687...%
  VSPS = (3/2+0+1+1+0+0)/6 = 3.5/6 = 0.583333...   (b has no completed goal)
  GVPE = switches / goals done = (3+0+0+2+2+0+0)/(2+0+3+1+1+2+1) = 7/10
  Interactions (is_interaction, scored): a steps 4-8 (5, all hit a component; targets at 4, 5,
  7, 8), b 1-4 (4 hit; targets 1, 3), c 1, 4-6 (step 4 out of range: no hit; targets 1, 5, 6),
  d 1, 2, 4, 5 (5 misses; targets 1, 2, 4), e 0, 2, 3 (all hit; targets 2, 3), f 0-4 (2 and 3
  miss; targets 0, 1, 4), g 0 (hit, target):
  EIR = (5+4+3+3+3+3+1)/(5+4+4+4+3+5+1) = 22/26 = 84.615384...%
  TIR = (4+2+3+3+2+3+1)/26 = 18/26 = 69.230769...%
  EER: non-switch scored steps a 7 (valid 6-9), b 6 (valid 1; 3 is repetitive), c 8 (valid 1,
  5, 6, 7), d 4 (valid 1), e 3 (valid 0, 3; 2 is dangerous), f 5 (valid 0; 4 is dangerous),
  g 1 (valid) -> 14/34 = 41.176470...%
  PSR: goals completed within C_opt_dyn: a g2 (1 <= 1), c g3 (0 <= 0), d g1 (2 <= 2), f g2
  (0 <= 0), g g1 (1 <= 1) -> 5 of 2+1+3+2+2+2+1 = 13 goals = 38.461538...%
  Distances (steps with one): a 0, 0, 627.589481 (w 3), 0, 0; b 0, 0; c 0, 665.648855 (w 1),
  0, 0; d 0, 0, 0, 340.066042 (w 2); e 0, 0; f 0, 0, 448.509452 (w 2), 444.571279 (w 3), 0;
  g 0 -> 23 steps.
  AvgDist  = (627.589481 + 665.648855 + 340.066042 + 448.509452 + 444.571279) / 23
  AvgWDist = (3*627.589481 + 665.648855 + 2*340.066042 + 2*448.509452 + 3*444.571279) / 23

Oven run (all five succeed):
  a: 2/2, L_opt 3, L_act 8 -> SPL 3/8; F1 1; 3 switches, VSPS 3/2.
  b: 1/1, L_opt 3, L_act 9 -> SPL 1/3; V {On Off Heating}, O {On Heating}: F1 4/5; 3
     switches, VSPS 3.
  c: 2/2, L_opt 3, L_act 5 -> SPL 3/5; V {Heating Fault Off On}, O {Heating Done On}: F1 4/7;
     2 switches, VSPS 1.
  d: 2/2, L_opt 3, L_act 8 -> SPL 3/8; V {Heating On}, O {Heating Done On}: F1 4/5; 1 switch
     (goal 1), VSPS 1/2.
  e: 1/1, L_opt 1, L_act 2 -> SPL 1/2; V {Heating Done On Off}, O {Heating Fault Off}: F1
     2*2/7 = 4/7; VSPS 0.
  SR = SSR = 100%;  SPL = (3/8+1/3+3/5+3/8+1/2)/5 = (131/60)/5 = 43.666666...%
  State-F1 = (1+4/5+4/7+4/5+4/7)/5 = (131/35)/5 = 74.857142...%
  VSPS = (1.5+3+1+0.5+0)/5 = 1.2;   GVPE = (3+3+2+1+0)/(2+1+2+2+1) = 9/8
  EIR: interactions a 0, 7 (2 hits), b 1, 2, 5, 7, 8 (5 misses), c 1, 2, 4 (3 hits), d 2, 5,
  6, 7 (2 misses), e 1 (hit) -> 13/15 = 86.666666...%;  TIR: a 2, b 3 (2, 7, 8), c 2 (2, 4),
  d 2 (6, 7), e 1 -> 10/15 = 66.666666...%
  EER: non-switch steps (failed Switch_view attempts are not operations): a 0, 2, 7 (valid 0,
  7), b 1, 2, 4, 5, 7, 8 (valid 1, 2, 4 (passive unlock), 8), c 1, 2, 4 (valid 2, 4; 1 is
  dangerous), d 0, 2, 3, 5, 6, 7 (valid 3, 6, 7), e 0, 1 (both valid) -> 13/20 = 65%
  PSR: a g1, c g2, d g2 (1 <= C_opt_dyn 1) -> 3 of 2+1+2+2+1 = 8 goals = 37.5%
  Distances: a 0, 0; b 0, 0, 0; c 0, 0; d 325 (w 1), 0, 0; e 0 -> 11 steps, sum 325:
  AvgDist = AvgWDist = 325/11
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import polars as pl
import pytest

import vge_analytics as va

from ..conftest import HAND, KETTLE_CASES, OVEN_CASES

KETTLE_DISTANCES = (627.589481, 665.648855, 340.066042, 448.509452, 444.571279)
KETTLE_WEIGHTS = (3, 1, 2, 2, 3)

EXPECTED = {
    "kettle-vlm": {
        "SR": 100 * 4 / 7,
        "SSR": 100 * 5 / 7,
        "SPL": 100 * 2.2 / 7,
        "State-F1": 100 * 619 / 735,
        "EIR": 100 * 22 / 26,
        "TIR": 100 * 18 / 26,
        "VSPS": 3.5 / 6,
        "GVPE": 7 / 10,
        "EER": 100 * 14 / 34,
        "PSR": 100 * 5 / 13,
        "AvgDist": sum(KETTLE_DISTANCES) / 23,
        "AvgWDist": sum(w * d for w, d in zip(KETTLE_WEIGHTS, KETTLE_DISTANCES, strict=True)) / 23,
    },
    "oven-human": {
        "SR": 100.0,
        "SSR": 100.0,
        "SPL": 100 * 131 / 300,
        "State-F1": 100 * 131 / 175,
        "EIR": 100 * 13 / 15,
        "TIR": 100 * 10 / 15,
        "VSPS": 1.2,
        "GVPE": 9 / 8,
        "EER": 65.0,
        "PSR": 37.5,
        "AvgDist": 325 / 11,
        "AvgWDist": 325 / 11,
    },
}
# The hand-worked distances are written with 6 decimals; everything else is exact.
TOLERANCE = {"AvgDist": 1e-6, "AvgWDist": 1e-6}

# What the derivation above assumed about the case files (log length per episode): if a case
# file changes, this fails first and says which derivation to redo.
LOG_LENGTHS = {
    "kettle_a_axonometric_errors": 10,
    "kettle_b_danger_repetitive_budget": 8,
    "kettle_c_parse_multigoal_chain": 8,
    "kettle_d_local_budget": 8,
    "kettle_e_log_ended": 5,
    "kettle_f_error_goal_fractional_lambda": 5,
    "kettle_g_reset_chain": 1,
    "dashboard_a_active_unlock": 8,
    "dashboard_b_passive_unlock": 9,
    "dashboard_c_fault_late_switch": 5,
    "dashboard_d_dyn_copt_validity": 8,
    "dashboard_e_neutral_wait": 2,
}


def _close(got: float | None, want: float, name: str) -> bool:
    tol = TOLERANCE.get(name, 1e-9)
    return got is not None and math.isclose(got, want, rel_tol=0.0, abs_tol=tol)


def test_case_files_are_the_ones_derived_from() -> None:
    assert set(LOG_LENGTHS) == set(KETTLE_CASES) | set(OVEN_CASES)
    for name, n in LOG_LENGTHS.items():
        doc = json.loads((HAND / f"{name}.json").read_text())
        assert len(doc["episode"]["steps"]) == n, f"{name} changed: redo its derivation"


def test_every_metric_equals_the_hand_value(hand_out: Path) -> None:
    df = va.metrics(hand_out)
    assert df.columns == ["run_id", "model", *va.METRIC_NAMES]
    assert df["run_id"].to_list() == ["kettle-vlm", "oven-human"]
    problems = []
    for row in df.iter_rows(named=True):
        for name, want in EXPECTED[row["run_id"]].items():
            if not _close(row[name], want, name):
                problems.append(f"{row['run_id']} {name}: got {row[name]!r}, hand value {want!r}")
    assert not problems, "\n".join(problems)


def test_pooled_over_both_runs(hand_out: Path) -> None:
    # by=[]: one row over everything. Episode means pool the 12 episodes, ratios pool counts:
    # SR = (4 + 5) / 12; EIR = (22 + 13) / (26 + 15); GVPE = (7 + 9) / (10 + 8).
    row = va.metrics(hand_out, by=[]).row(0, named=True)
    assert _close(row["SR"], 100 * 9 / 12, "SR")
    assert _close(row["EIR"], 100 * 35 / 41, "EIR")
    assert _close(row["GVPE"], 16 / 18, "GVPE")
    assert _close(row["PSR"], 100 * 8 / 21, "PSR")


def test_group_by_facet_and_episode_column(hand_out: Path) -> None:
    by_facet = va.metrics(hand_out, by="meta_history", metrics=["SR", "EIR"])
    assert by_facet.columns == ["meta_history", "SR", "EIR"]
    assert by_facet["meta_history"].to_list() == ["3", "full"]  # sorted
    assert _close(by_facet["SR"][1], 100 * 4 / 7, "SR")
    # n_goals is an episode column; EIR (steps) joins through the episode. Kettle 1-goal
    # episodes: b (4 interactions, 4 hits), g (1, 1); oven: b (5, 4), e (1, 1).
    by_goals = va.metrics(hand_out, by=["n_goals"], metrics=["SR", "EIR"])
    assert by_goals["n_goals"].to_list() == [1, 2, 3]
    one = by_goals.row(0, named=True)
    assert _close(one["SR"], 100 * 3 / 4, "SR")  # kettle b fails; g, oven b, e succeed
    assert _close(one["EIR"], 100 * 10 / 11, "EIR")


def test_step_column_groups_step_metrics_only(hand_out: Path) -> None:
    df = va.metrics(hand_out, by="action_type", metrics="EIR,TIR")
    assert "push" in df["action_type"].to_list()
    with pytest.raises(va.UnknownColumnError, match="action_type"):
        va.metrics(hand_out, by="action_type")


def test_empty_group_gives_null(hand_out: Path) -> None:
    # A filter matching nothing: every run still has its row, every metric is null.
    df = va.metrics(hand_out, where={"category": "NoSuchCategory"})
    assert df["run_id"].to_list() == ["kettle-vlm", "oven-human"]
    assert df.select(va.METRIC_NAMES).null_count().row(0) == (2,) * 12
    # Empty denominators inside a non-empty group: the oven run never waited -> TIR of
    # timed_wait steps is null, not a division error; the kettle run's switch_view group
    # has no interaction either.
    by_action = va.metrics(hand_out, by=["run_id", "action_type"], metrics=["TIR", "AvgDist"])
    waits = by_action.filter(pl.col("action_type") == "switch_view")
    assert waits.height == 2 and waits["TIR"].null_count() == 2
    # VSPS is null when no episode of the group completed a goal (kettle b alone).
    b = va.metrics(hand_out, where={"episode_id": "hw_kettle_b"}, metrics=["VSPS", "GVPE"])
    assert b.filter(pl.col("run_id") == "kettle-vlm")[["VSPS", "GVPE"]].row(0) == (None, None)


def test_filters_bind_values(hand_out: Path) -> None:
    evil = "x' OR 1=1 --"
    # A filter on a run column removes the runs themselves (no group left); the quote in the
    # value is data, never SQL.
    assert va.metrics(hand_out, where={"model": [evil]}, metrics="SR").height == 0
    df = va.metrics(hand_out, where={"episode_id": [evil]}, metrics="SR")
    assert df["SR"].null_count() == 2
    one = va.metrics(hand_out, where={"run_id": "kettle-vlm"}, by="run_id", metrics="SR")
    assert one["SR"].to_list()[0] == pytest.approx(100 * 4 / 7)


def test_unknown_metric_is_an_error(hand_out: Path) -> None:
    with pytest.raises(va.UnknownMetricError, match="unknown metric 'sr'.*did you mean SR"):
        va.metrics(hand_out, metrics=["sr"])
    with pytest.raises(va.UnknownMetricError):
        va.get_metric("F1")
    with pytest.raises(va.UnknownColumnError, match="unknown grouping/filter column 'nope'"):
        va.metrics(hand_out, by="nope")
    with pytest.raises(va.UnknownColumnError, match="lists cannot"):
        va.metrics(hand_out, by="goals", metrics="SR")


def test_episode_terms_add_up_to_the_metrics(hand_out: Path) -> None:
    terms = va.episode_terms(hand_out)
    assert terms.height == 12
    pooled = terms.group_by("run_id").agg(pl.exclude("episode_id").sum()).sort("run_id")
    df = va.metrics(hand_out)
    for name in va.METRIC_NAMES:
        scale = va.get_metric(name).scale
        got = (scale * pooled[f"{name}:num"] / pooled[f"{name}:den"]).to_list()
        for g, w in zip(got, df[name].to_list(), strict=True):
            assert math.isclose(g, w, rel_tol=1e-12), name


def test_stored_episode_columns_agree_with_query_time_definitions(hand_out: Path) -> None:
    # SPL and State-F1 are computed at query time from L_opt/L_act/success and the state
    # lists; PSR from steps_used/c_opt_dyn. They must agree with the replay's stored values.
    eps = va.episodes(hand_out)
    by_ep = {
        r["episode_id"]: r
        for r in va.episode_terms(hand_out, ["SPL", "State-F1"]).iter_rows(named=True)
    }
    for r in eps.iter_rows(named=True):
        t = by_ep[r["episode_id"]]
        assert math.isclose(100 * t["SPL:num"], 100 * r["spl"], abs_tol=1e-9)
        assert math.isclose(t["State-F1:num"], r["state_f1"], abs_tol=1e-9)
    goals = va.goals(hand_out)
    psr_terms = va.episode_terms(hand_out, ["PSR"])
    assert psr_terms["PSR:num"].sum() == goals["perfect"].sum()
