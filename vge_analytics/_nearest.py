"""The values nearest a mistyped one (difflib): what a one-line error names beside a run id,
an episode id or a filter value that is not there, so a typo gets an answer."""

from __future__ import annotations

import difflib
from collections.abc import Sequence

NEAREST = 3
"""How many of the nearest values a hint names."""
CUTOFF = 0.6
"""The least likeness (difflib's ratio) of a value named as near."""
LISTED = 10
"""Known values this few are listed whole when none is alike."""
MAX_TEXT = 200
"""Characters of a value compared (a longer one is cut there)."""


def _likeness(value: str, known: str) -> float:
    """How alike two texts are (difflib's ratio, case ignored), or `value` and a part of
    `known` as long as it: `Kettel` is like `ElectricKettle`."""
    a, b = value.lower(), known.lower()[:MAX_TEXT]
    matcher = difflib.SequenceMatcher(None, b, a)  # difflib caches its second text
    best = matcher.ratio()
    # A part of `known` is only looked for in a text already half alike (a fast filter).
    for start in range(1, len(b) - len(a) + 1) if CUTOFF > best >= CUTOFF / 2 else ():
        matcher.set_seq1(b[start : start + len(a)])
        if matcher.quick_ratio() > best:  # an upper bound of ratio(), much cheaper
            best = max(best, matcher.ratio())
    return best


def nearest(value: object, known: Sequence[object]) -> list[str]:
    """The (at most three) values of `known` most like `value`, as text, best first (ties
    in sort order); none below a likeness of 0.6."""
    text = str(value)[:MAX_TEXT]
    scored = [(_likeness(text, str(k)), str(k)) for k in known]
    ranked = sorted((-score, k) for score, k in scored if score >= CUTOFF)
    return [k for _, k in ranked[:NEAREST]]


def nearest_hint(value: object, known: Sequence[object], what: str) -> str:
    """What follows a one-line error about `value`, which is not one of `known` (`what`: what
    one of them is, `run`): `; nearest: a, b` when some are alike, else `; runs: x, y, z`
    when they are few, else `; 57 runs, none alike`."""
    what = f"{what}s"
    close = nearest(value, known)
    if close:
        return f"; nearest: {', '.join(close)}"
    if not known:
        return f"; no {what}"
    if len(known) <= LISTED:
        return f"; {what}: {', '.join(map(str, known))}"
    return f"; {len(known):,} {what}, none alike"


__all__ = ["nearest", "nearest_hint"]
