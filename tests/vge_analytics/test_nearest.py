"""The values nearest a mistyped one (vge_analytics/_nearest.py), worked out by hand."""

from __future__ import annotations

import pytest

from vge_analytics._nearest import MAX_TEXT, _likeness, nearest, nearest_hint


def test_likeness_by_hand() -> None:
    # difflib's ratio is 2 M / T (M matched characters, T both lengths together):
    # sim-vlm-z / sim-vlm-a: M = 8 of T = 18.
    assert _likeness("sim-vlm-z", "sim-vlm-a") == pytest.approx(16 / 18)
    # Kettel / ElectricKettle: the whole is 0.5 alike (M = 5, T = 20), the part `kettle`
    # (case ignored) 5/6 (M = 5, T = 12).
    assert _likeness("Kettel", "ElectricKettle") == pytest.approx(10 / 12)
    assert _likeness("Xyz", "Lamp") == 0.0


def test_nearest_best_first_ties_in_order_none_below_the_cutoff() -> None:
    runs = ["sim-vlm-f", "sim-human", "sim-vlm-b", "sim-vlm-a", "sim-vlm-c", "x"]
    assert nearest("sim-vlm-z", runs) == ["sim-vlm-a", "sim-vlm-b", "sim-vlm-c"]
    assert nearest("sim-vlm-f-hist", ["sim-vlm-f", "sim-vlm-f-hist3", "sim-vlm-f-hist0"]) == [
        "sim-vlm-f-hist0",  # 26/28
        "sim-vlm-f-hist3",
        "sim-vlm-f",  # 18/23
    ]
    assert nearest("Xyz", ["Lamp", "Razor"]) == []
    assert nearest(3, [1, 2, 30]) == ["30"]  # compared as text


def test_hints() -> None:
    assert nearest_hint("sim-hman", ["sim-human", "sim-vlm-a"], "run") == (
        "; nearest: sim-human, sim-vlm-a"
    )
    assert nearest_hint("Z", ["A", "B"], "run") == "; runs: A, B"
    assert nearest_hint("Z", [f"run-{k}" for k in range(11)], "run") == "; 11 runs, none alike"
    assert nearest_hint("Z", [], "run") == "; no runs"


def test_huge_values_are_cut() -> None:
    long = "sim-vlm-a" + "x" * 10**6
    assert nearest(long, ["sim-vlm-a"]) == []  # compared on its first MAX_TEXT characters
    assert nearest("sim-vlm-a", [long]) == []
    assert nearest("y" * MAX_TEXT + "z", ["y" * MAX_TEXT]) == ["y" * MAX_TEXT]
