"""`vge power`: from two runs and for planning, worked by hand on the 3 x 2 case."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

import vge_analytics as va
from vge_analytics.reports import plan, power_of_pair
from vge_analytics.reports.inference import z_sum


def test_power_of_a_pair_by_hand(clustered_out: Path) -> None:
    """A vs B: clustered SE sqrt(1944.44) = 44.096 over 3 devices of 2 episodes. MDE =
    (1.95996 + 0.84162) * 44.096 = 123.54 points; to detect 5 points: 3 * (123.54 / 5)^2
    = 1831.4, so 1832 devices, 3664 episodes."""
    row = power_of_pair(clustered_out, "A", "B").row(0, named=True)
    se = math.sqrt(1260000 / 648)
    assert row["se"] == pytest.approx(se) and row["deff"] == pytest.approx(1.75)
    assert row["mde"] == pytest.approx(z_sum(0.05, 0.8) * se)
    assert row["mde"] == pytest.approx(123.54, abs=0.01)
    assert (row["clusters_needed"], row["episodes_needed"]) == (1832, 3664)
    assert row["note"] is None


def test_planning_from_cluster_sizes_by_hand(clustered_out: Path) -> None:
    """Three devices of two episodes; ICC 0.5: deff = 1 + (2 - 1) * 0.5 = 1.5. Rates 0.5 and
    0.55: variance 0.25 + 0.2475 = 0.4975; episodes = 1.5 * 2.801585^2 * 0.4975 / 0.05^2 =
    2342.9 -> 2343, devices 2343 / 2 -> 1172."""
    row = plan(clustered_out, rate=0.5, delta=5, icc=0.5).row(0, named=True)
    assert (row["n_clusters"], row["n_episodes"], row["deff"]) == (3, 6, 1.5)
    expected = 1.5 * z_sum(0.05, 0.8) ** 2 * 0.4975 / 0.05**2
    assert row["episodes_needed"] == math.ceil(expected) == 2343
    assert row["clusters_needed"] == 1172
    assert row["mde"] == pytest.approx(100 * z_sum(0.05, 0.8) * math.sqrt(1.5 * 0.4975 / 6))
    assert row["icc_source"] == "given"


def test_planning_measures_the_icc_when_not_given(clustered_out: Path) -> None:
    """Per run, success within devices (kettle_1, kettle_2, kettle_3):
    A (1,0),(1,1),(0,0): MSB = 2 * ((1/2-1/2)^2 + (1/2)^2 + (1/2)^2) / 2 = 1/2, MSW = (1/2)/3
    = 1/6, ICC = (1/2 - 1/6) / (1/2 + 1/6) = 1/2; B (1,1),(0,1),(1,1): MSB = 2 * (2 * (1/6)^2 +
    (1/3)^2) / 2 = 1/6, MSW = 1/6, ICC 0; B-seed1 (1,0),(0,1),(0,1): means all 1/2: ICC 0
    (clipped: MSB 0); B-seed2 (0,1),(0,1),(1,0): 0. Median of (1/2, 0, 0, 0) = 0."""
    row = plan(clustered_out, rate=0.5).row(0, named=True)
    assert row["icc"] == 0.0 and row["icc_source"] == "measured (median of 4 runs)"
    assert row["deff"] == 1.0


def test_bad_input_is_one_line(clustered_out: Path, pair_out: Path) -> None:
    with pytest.raises(va.AnalyticsError, match="--delta must be a positive difference"):
        power_of_pair(clustered_out, "A", "B", delta=0)
    with pytest.raises(va.AnalyticsError, match="--rate is a success rate between 0 and 1"):
        plan(clustered_out, rate=50)
    with pytest.raises(va.AnalyticsError, match="passes 100%"):
        plan(clustered_out, rate=0.97, delta=5)
    with pytest.raises(va.AnalyticsError, match="--power must be between 0 and 1"):
        plan(clustered_out, rate=0.5, power=1.0)
    with pytest.raises(va.AnalyticsError, match="--icc must be between 0 and 1"):
        plan(clustered_out, rate=0.5, icc=-0.1)
    row = power_of_pair(pair_out, "A", "B").row(0, named=True)  # one device: a stated null
    assert row["se"] is None and row["clusters_needed"] is None
    assert "all in one device" in row["note"]
    with pytest.raises(va.AnalyticsError, match="no run of OUT measures an ICC"):
        plan(pair_out, rate=0.5)
