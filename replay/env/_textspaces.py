"""The text fields of `vge/Device-v0`'s observation, as spaces an async vector env can share.

`gymnasium.vector.AsyncVectorEnv` passes observations through shared memory unless told not
to, and Gymnasium lays out only fixed-size spaces there: a `Sequence` (the device's views)
is refused, and its `Text` layout indexes a fixed character set (instructions and feedback
may hold any character) and is read once, when the vector env is built, into strings that
never change. These two spaces register layouts of their own with Gymnasium's
`create_shared_memory`, `read_from_shared_memory` and `write_to_shared_memory` (single
dispatch on the space's class, Gymnasium's extension point; its own spaces are untouched):

- `AnyText(max_length)`: per environment, an int32 row `[length, code point, ...]`;
- `ViewNames()`: per environment, an int8 row of view codes (1 + rank in `VIEW_ORDER`, then 0).

What is read back is a live sequence over the rows (as a `Box` is a live array over its
buffer); a deep copy of it, which the vector env returns unless built with `copy=False`, is
the tuple of values a synchronous vector env returns.
"""

from __future__ import annotations

import multiprocessing
from collections.abc import Callable, Iterator, Sequence
from types import ModuleType
from typing import Any, Generic, TypeVar

import numpy as np
from gymnasium import spaces
from gymnasium.vector.utils import (
    create_shared_memory,
    read_from_shared_memory,
    write_to_shared_memory,
)

from ..semantics import VIEW_ORDER, VIEW_RANK

T = TypeVar("T")


class AnyText(spaces.Text):
    """Any Unicode text up to `max_length` characters (instructions and feedback come from the
    benchmark, in any script). Samples draw from the base class's character set."""

    def contains(self, x: Any) -> bool:
        return isinstance(x, str) and self.min_length <= len(x) <= self.max_length


class ViewNames(spaces.Sequence):
    """The views a device offers (PROTOCOL §1.2): distinct names of `VIEW_ORDER`, in the
    device's order."""

    def __init__(self, seed: int | np.random.Generator | None = None) -> None:
        longest = max(map(len, VIEW_ORDER))
        charset = "".join(sorted(set("".join(VIEW_ORDER))))
        super().__init__(spaces.Text(longest, min_length=1, charset=charset), seed=seed)

    def contains(self, x: Any) -> bool:
        return (
            isinstance(x, tuple)
            and len(set(x)) == len(x)
            and all(isinstance(v, str) and v in VIEW_RANK for v in x)
        )

    def sample(self, mask: Any = None, probability: Any = None) -> tuple[str, ...]:
        """Some views, each kept with probability 1/2, in `VIEW_ORDER` (masks are not read)."""
        keep = self.np_random.integers(0, 2, size=len(VIEW_ORDER))
        return tuple(v for v, k in zip(VIEW_ORDER, keep, strict=True) if k)

    def __repr__(self) -> str:
        return "ViewNames()"


class LiveRows(Sequence, Generic[T]):
    """The values of n environments, decoded from their shared-memory rows when read."""

    def __init__(self, rows: np.ndarray, decode: Callable[[np.ndarray], T]) -> None:
        self._rows = rows
        self._decode = decode

    def __len__(self) -> int:
        return len(self._rows)

    def __getitem__(self, index: int) -> T:  # type: ignore[override]
        return self._decode(self._rows[index])

    def __iter__(self) -> Iterator[T]:
        return (self._decode(row) for row in self._rows)

    def __deepcopy__(self, memo: dict[int, Any]) -> tuple[T, ...]:
        return tuple(self)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Sequence) and tuple(self) == tuple(other)

    def __repr__(self) -> str:
        return repr(tuple(self))


# ------------------------------------------------------------------ AnyText: [length, code points]


def _text_rows(space: AnyText, shared: Any) -> np.ndarray:
    return np.frombuffer(shared.get_obj(), dtype=np.int32).reshape(-1, space.max_length + 1)


def _decode_text(row: np.ndarray) -> str:
    # `surrogatepass`: a Python string may hold lone surrogates; they travel unchanged.
    return row[1 : 1 + int(row[0])].astype("<u4").tobytes().decode("utf-32-le", "surrogatepass")


@create_shared_memory.register(AnyText)
def _create_text(space: AnyText, n: int = 1, ctx: ModuleType = multiprocessing) -> Any:
    return ctx.Array(np.dtype(np.int32).char, n * (space.max_length + 1))  # type: ignore[attr-defined]


@read_from_shared_memory.register(AnyText)
def _read_text(space: AnyText, shared: Any, n: int = 1) -> LiveRows[str]:
    return LiveRows(_text_rows(space, shared)[:n], _decode_text)


@write_to_shared_memory.register(AnyText)
def _write_text(space: AnyText, index: int, value: str, shared: Any) -> None:
    if not space.contains(value):
        raise ValueError(f"{value[:40]!r}... is longer than {space.max_length} characters")
    codes = np.frombuffer(value.encode("utf-32-le", "surrogatepass"), dtype="<u4")
    row = _text_rows(space, shared)[index]
    row[0] = len(codes)
    row[1 : 1 + len(codes)] = codes


# ------------------------------------------------------------------ ViewNames: view codes


def _view_rows(shared: Any) -> np.ndarray:
    return np.frombuffer(shared.get_obj(), dtype=np.int8).reshape(-1, len(VIEW_ORDER))


def _decode_views(row: np.ndarray) -> tuple[str, ...]:
    return tuple(VIEW_ORDER[int(code) - 1] for code in row if code)


@create_shared_memory.register(ViewNames)
def _create_views(space: ViewNames, n: int = 1, ctx: ModuleType = multiprocessing) -> Any:
    return ctx.Array(np.dtype(np.int8).char, n * len(VIEW_ORDER))  # type: ignore[attr-defined]


@read_from_shared_memory.register(ViewNames)
def _read_views(space: ViewNames, shared: Any, n: int = 1) -> LiveRows[tuple[str, ...]]:
    return LiveRows(_view_rows(shared)[:n], _decode_views)


@write_to_shared_memory.register(ViewNames)
def _write_views(space: ViewNames, index: int, value: tuple[str, ...], shared: Any) -> None:
    row = _view_rows(shared)[index]
    row[:] = 0
    row[: len(value)] = [VIEW_RANK[v] + 1 for v in value]


__all__ = ["AnyText", "LiveRows", "ViewNames"]
