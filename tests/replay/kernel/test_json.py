"""`nested_beyond`: the depth bound on JSON text (PROTOCOL §1.5), counted openers first."""

from __future__ import annotations

import pytest

from replay.kernel import nested_beyond


@pytest.mark.parametrize(
    ("text", "limit", "expected"),
    [
        (b"", 3, -1),
        (b"[[[]]]", 3, -1),  # three levels: at the limit
        (b"[[[[]]]]", 3, 3),  # the fourth `[` opens level 4
        (b'{"a": [{"b": [1]}]}', 3, 13),  # `{ [ { [`: the second `[`, byte 13
        (b'["[[[[[[", "{{{{"]', 3, -1),  # ten openers, all but one inside strings
        (b'["\\"[[[[", [[[1]]]]', 3, 13),  # an escaped quote does not end the string
        (b'["\\\\", [[[1]]]]', 3, 9),  # an escaped backslash does: the `[`s count
        (b'["[[[[[[' + b"[" * 300, 3, -1),  # an unterminated string hides the rest
    ],
)
def test_the_first_opener_beyond_the_limit(text: bytes, limit: int, expected: int) -> None:
    assert nested_beyond(text, limit) == expected


def test_openers_in_strings_beyond_the_limit_are_not_levels() -> None:
    """More openers than the limit in all, few levels: the exact scan says so."""
    many = b'{"t": "' + b"[{" * 1000 + b'", "steps": [[[]]]}'
    assert nested_beyond(many, 256) == -1
    assert nested_beyond(many, 3) == many.index(b"[[[]]]") + 2
    deep = b"[" * 257 + b"]" * 257
    assert nested_beyond(deep, 256) == 256
    assert nested_beyond(deep, 257) == -1
