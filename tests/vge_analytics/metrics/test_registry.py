"""The metric registry: names as PROTOCOL §6 writes them, complete metadata, SQL files parsed.
The paper's twelve come first and are computed by default; the two metrics of continuation
runs follow them, computed when named."""

from __future__ import annotations

import pytest

import vge_analytics as va
from vge_analytics.store import quote_ident

PAPER_METRICS = ("SR", "SSR", "SPL", "State-F1", "EIR", "TIR", "VSPS", "GVPE", "EER", "PSR",
         "AvgDist", "AvgWDist")  # fmt: skip


def test_names_and_order_are_spec6() -> None:
    assert va.METRIC_NAMES == PAPER_METRICS
    assert va.CONTINUATION_METRICS == ("RecoveryRate", "StepsToRecover")
    assert tuple(va.registry()) == PAPER_METRICS + va.CONTINUATION_METRICS
    assert PAPER_METRICS[:9] == va.MAIN_TABLE
    assert va.MetricSet.builtin().defaults == PAPER_METRICS


METADATA = {
    "SR": ("higher", "percent", "episode-mean", "episodes"),
    "SSR": ("higher", "percent", "episode-mean", "episodes"),
    "SPL": ("higher", "percent", "episode-mean", "episodes"),
    "State-F1": ("higher", "percent", "episode-mean", "episodes"),
    "EIR": ("higher", "percent", "step-ratio", "steps"),
    "TIR": ("higher", "percent", "step-ratio", "steps"),
    "VSPS": ("lower", "ratio", "episode-mean", "episodes"),
    "GVPE": ("lower", "ratio", "run-level ratio", "episodes"),
    "EER": ("higher", "percent", "step-ratio", "steps"),
    "PSR": ("higher", "percent", "goal-ratio", "goals"),
    "AvgDist": ("lower", "distance", "step-ratio", "steps"),
    "AvgWDist": ("lower", "distance", "step-ratio", "steps"),
    "RecoveryRate": ("higher", "percent", "episode-mean", "episodes"),
    "StepsToRecover": ("lower", "ratio", "episode-mean", "episodes"),
}
"""(direction, unit, level, grain) of each built-in, as docs/METRICS.md's table states them."""


@pytest.mark.parametrize("name", PAPER_METRICS + ("RecoveryRate", "StepsToRecover"))
def test_metadata(name: str) -> None:
    m = va.get_metric(name)
    assert m.name == name
    assert (m.direction, m.unit, m.level, m.grain) == METADATA[name]
    assert m.version >= 1
    assert len(m.definition) > 40 and m.null_rule
    assert m.numerator and m.denominator
    assert m.source.startswith("vge_analytics/sql/") and m.source.endswith(".sql")


def test_directions_and_units_follow_the_paper() -> None:
    lower = {n for n in PAPER_METRICS if va.get_metric(n).direction == "lower"}
    assert lower == {"VSPS", "GVPE", "AvgDist", "AvgWDist"}
    ratios = {n for n in PAPER_METRICS if va.get_metric(n).unit != "percent"}
    assert ratios == {"VSPS", "GVPE", "AvgDist", "AvgWDist"}
    assert va.get_metric("SR").scale == 100.0 and va.get_metric("VSPS").scale == 1.0
    assert va.get_metric("GVPE").level == "run-level ratio"
    assert va.get_metric("PSR").level == "goal-ratio"
    assert va.get_metric("EIR").level == "step-ratio"


def test_unknown_names() -> None:
    for bad in ("sr", "F1", "", "SR;DROP"):
        with pytest.raises(va.UnknownMetricError):
            va.get_metric(bad)
    with pytest.raises(va.UnknownMetricError, match="did you mean State-F1"):
        va.get_metric("state-f1")


def test_metric_table() -> None:
    table = va.metric_table()
    assert table["metric"].to_list() == [*PAPER_METRICS, *va.CONTINUATION_METRICS]
    assert {"direction", "unit", "level", "version", "definition"} <= set(table.columns)


def test_quote_ident() -> None:
    assert quote_ident("model") == '"model"'
    assert quote_ident('a"b') == '"a""b"'
    assert quote_ident('x" ; DROP VIEW steps; --') == '"x"" ; DROP VIEW steps; --"'
