"""`py_column`: columns of Python values made from their buffers, equal to `pa.array`'s."""

from __future__ import annotations

import math

import numpy as np
import pyarrow as pa
import pytest

from replay.semantics import py_column, validity_bitmap

CASES = [
    (["a", None, "é", "", "🙂"], pa.string()),
    ([1, None, -5, 2**63 - 1], pa.int64()),
    ([1.5, None, 2, -0.0], pa.float64()),
    ([True, None, False] * 5, pa.bool_()),  # more than 8 rows: a bitmap of two bytes
    ([], pa.string()),
    ([None, None], pa.int64()),
    ([[1, 2], None, []], pa.list_(pa.int64())),  # other types: pa.array's own
]


@pytest.mark.parametrize(("values", "type_"), CASES)
def test_the_same_column_as_pa_array(values: list, type_: pa.DataType) -> None:
    got = py_column(values, type_)
    got.validate(full=True)
    assert got.type == type_
    assert got.equals(pa.array(values, type_))
    assert got.to_pylist() == values


def test_floats_keep_their_bits() -> None:
    got = py_column([math.nan, -0.0, math.inf], pa.float64()).to_pylist()
    assert math.isnan(got[0]) and got[0] is not None
    assert math.copysign(1.0, got[1]) == -1.0 and got[2] == math.inf


def test_what_pa_array_refuses_is_refused() -> None:
    with pytest.raises(OverflowError):
        py_column([2**63], pa.int64())
    with pytest.raises(UnicodeEncodeError):
        py_column(["\ud800"], pa.string())


def test_validity_bitmap() -> None:
    assert validity_bitmap(np.ones(5, np.bool_)) == (None, 0)
    bitmap, nulls = validity_bitmap(np.array([1, 0, 1, 1, 0, 0, 0, 0, 1], np.uint8))
    assert nulls == 5
    assert bitmap is not None and bitmap.to_pybytes() == bytes([0b00001101, 0b1])
