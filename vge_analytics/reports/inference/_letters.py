"""The compact letter display of a ranking: runs that share a letter are not distinguishable
(no significant difference between any two of them).

Insert and absorb (Piepho 2004): start with one letter shared by every run; for each
significant pair, every letter held by both is split in two (one without each run of the
pair), then a letter whose runs are all in another letter's is dropped. What remains is
every largest set of runs with no significant pair among them (each step keeps exactly the
maximal sets of the pairs seen so far), so the display does not depend on the order of the
pairs. Letters are given in ranking order: `a` to the set holding the best run, and so on.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from string import ascii_lowercase

MAX_LETTERS = 1000
"""The most tied groups a display may hold (a pathological pattern of significances could
need exponentially many; it is refused before)."""


class TooManyGroupsError(ValueError):
    """The significances need more than MAX_LETTERS letters."""


def _letter(i: int) -> str:
    """a..z, then aa, ab, ... (spreadsheet order)."""
    name = ""
    i += 1
    while i:
        i, r = divmod(i - 1, 26)
        name = ascii_lowercase[r] + name
    return name


def tied_groups(n: int, significant: Iterable[tuple[int, int]]) -> list[frozenset[int]]:
    """The maximal sets of positions 0..n-1 with no significant pair inside, each sorted by
    its best (lowest) position."""
    groups: list[frozenset[int]] = [frozenset(range(n))] if n else []
    for i, j in sorted({(min(p), max(p)) for p in significant if p[0] != p[1]}):
        split: list[frozenset[int]] = []
        for g in groups:
            if i in g and j in g:
                split.extend((g - {i}, g - {j}))
            else:
                split.append(g)
        unique = sorted(set(split), key=lambda g: (-len(g), sorted(g)))
        groups = [g for k, g in enumerate(unique) if not any(g < h for h in unique[:k])]
        if len(groups) > MAX_LETTERS:
            raise TooManyGroupsError(f"the significances form more than {MAX_LETTERS} tied groups")
    return sorted(groups, key=lambda g: sorted(g))


def compact_letters(n: int, significant: Iterable[tuple[int, int]]) -> list[str]:
    """The letters of each position 0..n-1 (0 the best ranked): runs sharing a letter are
    not significantly different."""
    letters = [""] * n
    for k, group in enumerate(tied_groups(n, significant)):
        for i in sorted(group):
            letters[i] += _letter(k)
    return letters


def letters_of(ranked: Sequence[str], significant: Iterable[tuple[str, str]]) -> dict[str, str]:
    """`compact_letters` by name: {run: letters} for runs in ranking order."""
    where = {name: i for i, name in enumerate(ranked)}
    pairs = [(where[a], where[b]) for a, b in significant]
    return dict(zip(ranked, compact_letters(len(ranked), pairs), strict=True))


__all__ = ["compact_letters", "letters_of", "MAX_LETTERS", "tied_groups", "TooManyGroupsError"]
