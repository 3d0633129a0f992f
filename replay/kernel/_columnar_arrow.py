"""Array helpers of the columnar replay: ragged ranges of table rows, and Arrow arrays
from numpy columns and integer codes."""

from __future__ import annotations

import numpy as np
import pyarrow as pa

STRING = pa.string()
STRING_LIST = pa.list_(STRING)


def ragged_rows(starts: np.ndarray, counts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(owner, row) pairs: for each i, the rows starts[i] .. starts[i] + counts[i] - 1."""
    owner = np.repeat(np.arange(len(counts)), counts)
    first = np.cumsum(counts) - counts
    row = np.arange(int(counts.sum())) - np.repeat(first - starts, counts)
    return owner, row


def numbers(values: np.ndarray, type_: pa.DataType, valid: np.ndarray | None = None) -> pa.Array:
    """A numeric or boolean array; null where `valid` is false."""
    if valid is None or valid.all():
        return pa.array(values, type=type_)
    return pa.array(values, type=type_, mask=~valid)


def scatter(n: int, rows: np.ndarray, values: np.ndarray, fill: object = 0) -> np.ndarray:
    """A length-n array holding `values` at `rows` and `fill` elsewhere."""
    out = np.full(n, fill, dtype=values.dtype)
    out[rows] = values
    return out


def ragged_strings(counts: np.ndarray, values: pa.Array) -> pa.Array:
    """A list<string> column: element i holds the next `counts[i]` strings of `values`."""
    offsets = np.zeros(len(counts) + 1, np.int32)
    np.cumsum(counts, out=offsets[1:])
    return pa.ListArray.from_arrays(pa.array(offsets), values)


class Vocab:
    """An Arrow array mirroring a growing Python list (rebuilt when the list grew), to
    turn integer codes into a column with one `take`."""

    def __init__(self, values: list, type_: pa.DataType = STRING) -> None:
        self.values = values
        self.type = type_
        self._array = pa.array([], type_)

    def take(self, codes: np.ndarray) -> pa.Array:
        """`values[code]` per element; a negative code is null."""
        if len(self._array) != len(self.values):
            self._array = pa.array(self.values, self.type)
        negative = codes < 0
        if negative.any():
            return self._array.take(pa.array(codes, pa.int64(), mask=negative))
        return self._array.take(pa.array(codes, pa.int64()))


def take_rows(array: pa.Array, rows: np.ndarray) -> pa.Array:
    return array.take(pa.array(rows.astype(np.int64)))
