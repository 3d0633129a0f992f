"""Error-type distribution (the paper's pie) and switch classes, against hand counts.

Kettle run (hand-worked expected error types of the scored steps): a: action_error (0, 4),
switch_view_pn (2), params_error (5), component_selection (6); b: invalid_waiting (0, 5),
component_selection (2, 4); c: action_error (0, 2, 3), invalid_coord (4); d: params_error
(2, 4), invalid_coord (5); e: component_selection (0); f: params_error (1), invalid_coord
(2, 3); g: none. Totals: invalid_coord 4, component_selection 4, params_error 4,
action_error 5, invalid_waiting 2, switch_view_nn 0, switch_view_pn 1 = 20 errors.
Oven run: a: switch_view_nn (1, 4), action_error (2, 3, 5); b: switch_view_nn (0, 3),
component_selection (1), invalid_coord (5), action_error (7); c: switch_view_nn (0),
component_selection (1); d: action_error (0, 1), invalid_coord (2), component_selection (5);
e: none. Totals: 2, 3, 0, 6, 0, 5, 0 = 16.
Switch classes: kettle a NP PN NP, d NP PP, e PP (+ one switch with no class: goal without
targets) -> NP 3, PN 1, NN 0, PP 2 of 7 switches; oven a NN NN NP, b NN NN NP, c NN NP,
d NP -> NP 4, NN 5 of 9.
"""

from __future__ import annotations

from pathlib import Path

import polars as pl

import vge_analytics as va

KETTLE = [4, 4, 4, 5, 2, 0, 1]
OVEN = [2, 3, 0, 6, 0, 5, 0]


def test_error_distribution(hand_out: Path) -> None:
    df = va.error_distribution(hand_out)
    assert df.columns == ["run_id", "model", "error_group", "error_type", "count", "share"]
    for run, counts in (("kettle-vlm", KETTLE), ("oven-human", OVEN)):
        part = df.filter(pl.col("run_id") == run)
        assert part["error_type"].to_list() == list(va.ERROR_TYPES)
        assert part["count"].to_list() == counts
        total = sum(counts)
        assert part["share"].to_list() == [100 * c / total for c in counts]
    groups = va.error_groups(hand_out, by="run_id")
    kettle = groups.filter(pl.col("run_id") == "kettle-vlm")
    assert kettle["error_group"].to_list() == ["grounding", "execution", "navigation"]
    assert kettle["count"].to_list() == [8, 11, 1]
    assert kettle["share"].to_list() == [40.0, 55.0, 5.0]


def test_error_distribution_empty_group_is_null(hand_out: Path) -> None:
    # kettle_g has no error at all: counts 0, shares null (not a division error).
    df = va.error_distribution(hand_out, by="episode_id", where={"episode_id": "hw_kettle_g"})
    assert df.height == 7
    assert df["count"].sum() == 0 and df["share"].null_count() == 7


def test_switch_classes(hand_out: Path) -> None:
    df = va.switch_classes(hand_out)
    assert df.columns == ["run_id", "model", "switch_class", "count", "share", "switches"]
    kettle = df.filter(pl.col("run_id") == "kettle-vlm")
    assert kettle["switch_class"].to_list() == ["NP", "PN", "NN", "PP"]
    assert kettle["count"].to_list() == [3, 1, 0, 2]
    assert kettle["switches"].to_list() == [7] * 4
    assert kettle["share"].to_list() == [50.0, 100 / 6, 0.0, 100 * 2 / 6]
    oven = df.filter(pl.col("run_id") == "oven-human")
    assert oven["count"].to_list() == [4, 0, 5, 0]


def test_steps_with_error_drill_down(hand_out: Path) -> None:
    rows = va.steps_with_error(hand_out, "invalid_coord", where={"run_id": "kettle-vlm"})
    got = list(zip(rows["episode_id"], rows["step"], strict=True))
    assert got == [
        ("hw_kettle_c", 4),
        ("hw_kettle_d", 5),
        ("hw_kettle_f", 2),
        ("hw_kettle_f", 3),
    ]
    nav = va.steps_with_error(hand_out, "navigation", columns=["episode_id", "error_type"])
    assert nav.height == 6 and set(nav["error_type"]) == {"switch_view_nn", "switch_view_pn"}
