"""The polars implementation of the metrics agrees with the DuckDB one (to 1e-9)."""

from __future__ import annotations

from pathlib import Path

import polars as pl
import pytest

import vge_analytics as va

GROUPINGS = (
    None,
    [],
    ["model"],
    ["category", "meta_history"],
    ["n_goals"],
    ["termination", "agent_kind"],
    ["device_id", "episode_id"],
)


def assert_agree(duck: pl.DataFrame, polar: pl.DataFrame) -> None:
    assert duck.columns == polar.columns
    assert duck.height == polar.height
    keys = [c for c in duck.columns if c not in va.METRIC_NAMES]
    if keys:
        assert duck.select(keys).equals(polar.select(keys))
    for name in (c for c in duck.columns if c in va.METRIC_NAMES):
        for a, b in zip(duck[name].to_list(), polar[name].to_list(), strict=True):
            assert (a is None) == (b is None), name
            if a is not None:
                assert abs(a - b) <= 1e-9, (name, a, b)


@pytest.mark.parametrize("by", GROUPINGS, ids=str)
def test_polars_agrees_on_hand_runs(hand_out: Path, by) -> None:
    assert_agree(va.metrics(hand_out, by=by), va.polars_metrics(hand_out, by=by))


def test_polars_agrees_on_pair(pair_out: Path) -> None:
    assert_agree(va.metrics(pair_out), va.polars_metrics(pair_out))


SAMPLE_GROUPINGS = (
    None,
    ["model"],
    ["category"],
    ["n_goals", "agent_kind"],
    ["meta_history_length"],
)


@pytest.mark.parametrize("by", SAMPLE_GROUPINGS, ids=str)
def test_polars_agrees_on_bundled_sample(sample_out: Path, by) -> None:
    duck = va.metrics(sample_out, by=by)
    assert duck.height >= 2
    assert_agree(duck, va.polars_metrics(sample_out, by=by))
