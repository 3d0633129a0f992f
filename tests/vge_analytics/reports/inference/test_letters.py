"""The compact letter display: by hand, and equal to every maximal set without a
significant pair (brute force) whatever the order of the pairs."""

from __future__ import annotations

import itertools

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from vge_analytics.reports.inference import (
    MAX_LETTERS,
    TooManyGroupsError,
    compact_letters,
    letters_of,
    tied_groups,
)


def test_letters_by_hand() -> None:
    assert compact_letters(3, []) == ["a", "a", "a"]
    assert compact_letters(3, [(0, 1), (0, 2), (1, 2)]) == ["a", "b", "c"]
    # four runs best first; 0-2, 0-3 and 1-3 differ: {0, 1}, {1, 2}, {2, 3} are tied
    assert compact_letters(4, [(0, 2), (3, 0), (1, 3)]) == ["a", "ab", "bc", "c"]
    assert letters_of(["x", "y", "z"], [("x", "z")]) == {"x": "a", "y": "ab", "z": "b"}
    assert compact_letters(0, []) == []


def _brute_force(n: int, significant: set[tuple[int, int]]) -> set[frozenset[int]]:
    free = [
        frozenset(s)
        for r in range(1, n + 1)
        for s in itertools.combinations(range(n), r)
        if not any((i, j) in significant for i, j in itertools.combinations(s, 2))
    ]
    return {s for s in free if not any(s < t for t in free)}


@settings(max_examples=150, deadline=None)
@given(
    st.integers(1, 7).flatmap(
        lambda n: st.tuples(
            st.just(n),
            st.lists(st.tuples(st.integers(0, n - 1), st.integers(0, n - 1)), max_size=15),
        )
    )
)
def test_groups_are_every_maximal_tied_set(case) -> None:
    n, pairs = case
    significant = {(min(i, j), max(i, j)) for i, j in pairs if i != j}
    groups = tied_groups(n, pairs)
    assert set(groups) == _brute_force(n, significant)
    assert tied_groups(n, list(reversed(pairs))) == groups


def test_a_pathological_pattern_is_refused() -> None:
    """Significant pairs inside each of 7 triples: one run of each triple may share a letter,
    so 3^7 = 2187 tied groups, more than MAX_LETTERS."""
    pairs = [(3 * t + i, 3 * t + j) for t in range(7) for i, j in ((0, 1), (0, 2), (1, 2))]
    assert MAX_LETTERS < 3**7
    with pytest.raises(TooManyGroupsError, match="more than 1000 tied groups"):
        compact_letters(21, pairs)
