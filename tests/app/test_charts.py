"""The charts' encodings (app/_charts.py) as Vega-Lite specs: one style per series, legends
that list everything, axes that name every group, shares on 0..100, rounded tooltips.
How Chromium draws them with thirty runs: tests/app/test_browser_charts.py."""

from __future__ import annotations

import json

import polars as pl

from app import _charts as charts


def names(n: int) -> list[str]:
    return [f"run-{k:03d}" for k in range(n)]


def test_series_styles_tell_eighty_series_apart_by_colour_and_shape() -> None:
    styles = charts.series_styles(names(80))
    assert len({(s.color, s.shape) for s in styles.values()}) == 80
    # Series 0..9 differ by colour alone, 10..19 repeat the colours with the second shape.
    assert [s.color for s in list(styles.values())[:10]] == list(charts.SERIES_COLORS)
    assert {s.shape for s in list(styles.values())[:10]} == {"circle"}
    assert styles["run-010"] == ("#4e79a7", "square", (6, 3))
    # Past 80 a colour and shape come back, with another dash: lines stay apart up to 240.
    more = list(charts.series_styles(names(240)).values())
    assert (more[80].color, more[80].shape) == (more[0].color, more[0].shape)
    assert len(set(more)) == 240


def test_series_styles_follow_the_order_given() -> None:
    first = charts.series_styles(["b", "a", "b", "c"])
    assert list(first) == ["b", "a", "c"]  # a name given twice is one series
    assert first == charts.series_styles(["b", "a", "c"])
    assert first["b"].color == charts.SERIES_COLORS[0]


def _channels(spec: dict) -> dict:
    return spec["encoding"] if "encoding" in spec else spec["spec"]["encoding"]


def test_series_encoding_makes_one_legend_that_lists_and_names_everything() -> None:
    groups = names(30)
    gain = pl.DataFrame(
        {
            "group": [g for g in groups for _ in range(2)],
            "lambda": [2.0, 3.0] * 30,
            "SR": [50.0, 58.333333] * 30,
            "gain": [0.0, 8.333333] * 30,
        }
    )
    spec = charts.sweep_lines(gain, "gain").to_dict()
    encoding = _channels(spec)
    for channel in ("color", "shape", "strokeDash"):
        assert encoding[channel]["scale"]["domain"] == groups, channel
        assert encoding[channel]["legend"]["symbolLimit"] == 0
        assert encoding[channel]["legend"]["labelLimit"] == 0
    styles = charts.series_styles(groups)
    assert encoding["color"]["scale"]["range"] == [s.color for s in styles.values()]
    assert encoding["shape"]["scale"]["range"] == [s.shape for s in styles.values()]
    assert spec["height"] >= 20 * 30  # the legend fits beside the plot
    tooltips = {t["field"]: t.get("format") for t in encoding["tooltip"]}
    assert tooltips["SR"] == tooltips["gain"] == ".2f"


def test_bars_name_every_group_and_shares_stay_within_0_to_100() -> None:
    groups = ["random-cut (incomplete)", *names(29)]
    classes = pl.DataFrame(
        {
            "group": groups,
            "switch_class": ["NP"] * 30,
            "count": [3] * 30,
            "share": [100.00000000001] * 30,  # a sum of shares, a hair over 100
        }
    )
    spec = charts.switch_stacked(classes, groups).to_dict()
    encoding = _channels(spec)
    assert encoding["y"]["axis"]["labelLimit"] == 0  # never "random-cut (i"
    assert encoding["y"]["axis"]["labelOverlap"] is False  # never every other name
    assert encoding["x"]["scale"] == {"domain": [0, 100], "nice": False, "clamp": True}
    share = next(t for t in encoding["tooltip"] if t["field"] == "share")
    assert share["format"] == ".1f"  # 58.3, not 58.3333


def test_metric_bars_name_every_group_in_rows_of_panels() -> None:
    groups = ["random-cut (incomplete)", "x" * 50, *names(28)]
    long = pl.DataFrame(
        {
            "group": groups * 2,
            "metric": ["SR"] * 30 + ["SPL"] * 30,
            "value": [58.333333] * 60,
            "direction": ["higher"] * 60,
        }
    )
    spec = charts.metric_bars(long, ["SR", "SPL"], groups).to_dict()
    assert spec["columns"] == 3  # 940 px: a 312 px label column and three 170 px panels
    inner = spec["spec"]["encoding"]
    assert inner["y"]["field"] == "group" and inner["y"]["axis"]["labelLimit"] == 0
    assert inner["color"]["scale"]["domain"] == groups
    assert "legend" in inner["color"] and inner["color"]["legend"] is None
    assert json.dumps(spec).count('"format": ".2f"') == 1  # the value's tooltip
