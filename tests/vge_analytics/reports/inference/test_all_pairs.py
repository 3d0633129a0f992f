"""`compare_all` (`vge compare OUT --all`): each pair as `compare` reports it, the correction
across pairs, the ranking and its tied groups, and the bad inputs."""

from __future__ import annotations

from pathlib import Path

import polars as pl
import pytest

import vge_analytics as va
from vge_analytics.reports import compare_all


def test_every_pair_is_the_pairs_comparison(clustered_out: Path) -> None:
    """Ranking by SR: B 5/6, then A, B-seed1 and B-seed2 at 3/6 each (tied, by name). With
    three devices the smallest exact p-value is 2/8, so after Holm over the six pairs no pair
    differs and every run shares the letter a."""
    result = compare_all(clustered_out)
    ranking = result.ranking
    assert ranking["run_id"].to_list() == ["B", "A", "B-seed1", "B-seed2"]
    assert ranking["rank"].to_list() == [1, 2, 2, 2]
    assert ranking["SR"].to_list() == pytest.approx([500 / 6, 50.0, 50.0, 50.0])
    assert ranking["letters"].to_list() == ["a"] * 4
    pairs = result.pairs
    assert pairs.height == 6 and not pairs["significant"].any()
    row = pairs.filter((pl.col("run_id_a") == "B") & (pl.col("run_id_b") == "A")).row(0, named=True)
    single = va.compare(clustered_out, "B", "A", metrics="SR").metrics.row(0, named=True)
    for key in ("A", "B", "diff", "ci_low", "ci_high", "se", "deff", "p_value"):
        assert row[key] == single[key], key
    assert (row["n_common"], row["n_clusters"], row["p_value"]) == (6, 3, 0.75)
    holm = sorted(p for p in pairs["p_value"])
    assert min(pairs["p_adjusted"]) == pytest.approx(min(1.0, 6 * holm[0]))
    s = result.summary.row(0, named=True)
    assert (s["entries"], s["pairs"], s["pairs_tested"], s["significant"]) == (4, 6, 6, 0)


def test_groups_of_runs_by_model(clustered_out: Path) -> None:
    """model-b pools B and its two seeds: 11 successes in 18 episode plays, 61.11."""
    result = compare_all(clustered_out, by="model")
    assert result.ranking["model"].to_list() == ["model-b", "model-a"]
    assert result.ranking["SR"].to_list() == pytest.approx([1100 / 18, 50.0])
    (row,) = result.pairs.iter_rows(named=True)
    assert (row["model_a"], row["model_b"], row["n_common"]) == ("model-b", "model-a", 6)
    assert row["diff"] == pytest.approx(50.0 - 1100 / 18)


def test_a_tied_group_on_the_sample(sample_out: Path) -> None:
    """The sample's strongest model with history 3 and unlimited (56.09 and 54.49) are not
    distinguishable (they share b), nor sim-vlm-c from either of its neighbours (ef); every
    other pair differs."""
    result = compare_all(sample_out)
    assert result.ranking["run_id"].to_list() == [
        "sim-human", "sim-vlm-f-hist3", "sim-vlm-f", "sim-vlm-f-hist0",
        "sim-vlm-e", "sim-vlm-d", "sim-vlm-c", "sim-vlm-b", "sim-vlm-a",
    ]  # fmt: skip
    assert result.ranking["letters"].to_list() == ["a", "b", "b", "c", "d", "e", "ef", "f", "g"]
    tied = result.pairs.filter(~pl.col("significant"))
    assert {(r["run_id_a"], r["run_id_b"]) for r in tied.iter_rows(named=True)} == {
        ("sim-vlm-f-hist3", "sim-vlm-f"),
        ("sim-vlm-d", "sim-vlm-c"),
        ("sim-vlm-c", "sim-vlm-b"),
    }


def test_nulls_are_stated_and_errors_are_one_line(pair_out: Path, hand_out: Path) -> None:
    # one device: no interval or test, so not distinguishable
    (row,) = compare_all(pair_out).pairs.iter_rows(named=True)
    assert row["n_clusters"] == 1 and row["p_value"] is None and row["significant"] is False
    # no common episode: n_common 0, nulls
    (row,) = compare_all(hand_out).pairs.iter_rows(named=True)
    assert row["n_common"] == 0 and row["diff"] is None and row["significant"] is False
    with pytest.raises(va.AnalyticsError, match="needs two or more model values"):
        compare_all(hand_out, runs=["kettle-vlm"], by="model")
    with pytest.raises(va.UnknownColumnError, match="--by 'nope'"):
        compare_all(hand_out, by="nope")
    with pytest.raises(va.UnknownRunError, match="unknown run 'Z'"):
        compare_all(hand_out, runs=["Z", "kettle-vlm"])
    with pytest.raises(va.AnalyticsError, match="alpha must be between 0 and 1"):
        compare_all(hand_out, alpha=1.5)
    with pytest.raises(va.AnalyticsError, match="unknown cluster 'run'"):
        compare_all(hand_out, cluster="run")
