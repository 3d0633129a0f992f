"""Rows -> Arrow tables, with the Arrow schema derived from the row classes (`_rows.py`).

The row classes are the one declaration of the columns; this module only maps their
annotations to Arrow types, so the Parquet schema can never drift from the records.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import cache
from typing import Any

import msgspec
import numpy as np
import pyarrow as pa

from ._records import SCHEMA_VERSION

_SCALARS = {
    msgspec.inspect.StrType: pa.string(),
    msgspec.inspect.IntType: pa.int64(),
    msgspec.inspect.FloatType: pa.float64(),
    msgspec.inspect.BoolType: pa.bool_(),
}


def _arrow_type(info: msgspec.inspect.Type) -> tuple[pa.DataType, bool]:
    """(arrow type, nullable) of a msgspec type."""
    if isinstance(info, msgspec.inspect.Metadata):
        return _arrow_type(info.type)
    if isinstance(info, msgspec.inspect.UnionType):
        members = [t for t in info.types if not isinstance(t, msgspec.inspect.NoneType)]
        if len(members) != 1:
            raise TypeError(f"unsupported union {info}")
        return _arrow_type(members[0])[0], True
    if isinstance(info, msgspec.inspect.ListType):
        inner, _ = _arrow_type(info.item_type)
        return pa.list_(inner), False
    for kind, arrow in _SCALARS.items():
        if isinstance(info, kind):
            return arrow, False
    raise TypeError(f"unsupported column type {info}")


@cache
def arrow_schema(row_type: type) -> pa.Schema:
    """Arrow schema of a row class; column names are the encoded (PROTOCOL §7) names."""
    info = msgspec.inspect.type_info(row_type)
    fields = []
    for f in info.fields:
        arrow, nullable = _arrow_type(f.type)
        fields.append(pa.field(f.encode_name, arrow, nullable=nullable))
    return pa.schema(fields, metadata={b"vge_schema_version": str(SCHEMA_VERSION).encode()})


_NUMPY_TYPES = {pa.bool_(): np.bool_, pa.int64(): np.int64, pa.float64(): np.float64}


def validity_bitmap(valid: np.ndarray) -> tuple[pa.Buffer | None, int]:
    """(Arrow validity bitmap, null count) of a column valid where `valid` is true; no bitmap
    when nothing is null."""
    nulls = int(len(valid) - np.count_nonzero(valid))
    if not nulls:
        return None, 0
    return pa.py_buffer(np.packbits(valid.astype(np.bool_), bitorder="little")), nulls


def py_column(values: Sequence[Any], type_: pa.DataType) -> pa.Array:
    """A string, boolean, int64 or float64 column of Python values (None: null), made from
    its buffers, as `pa.array(values, type_)` makes it: `pa.array` imports pandas on its
    first call, a quarter of a second of CPU in a process that needs no pandas (a replay,
    its workers). Other types go to `pa.array`."""
    valid = np.fromiter((v is not None for v in values), np.bool_, len(values))
    bitmap, nulls = validity_bitmap(valid)
    if type_ == pa.string():
        encoded = [b"" if v is None else v.encode("utf-8") for v in values]
        offsets = np.zeros(len(encoded) + 1, np.int64)
        np.cumsum([len(e) for e in encoded], out=offsets[1:])
        if offsets[-1] > 0x7FFFFFFF:
            raise OverflowError("string column over 2 GiB")
        data, offsets = pa.py_buffer(b"".join(encoded)), pa.py_buffer(offsets.astype(np.int32))
        return pa.StringArray.from_buffers(len(encoded), offsets, data, bitmap, nulls)
    dtype = _NUMPY_TYPES.get(type_)
    if dtype is None:
        return pa.array(values, type_)
    data = np.array([0 if v is None else v for v in values], dtype)
    if type_ == pa.bool_():
        data = np.packbits(data, bitorder="little")
    return pa.Array.from_buffers(type_, len(values), [bitmap, pa.py_buffer(data)], nulls)


def rows_to_table(rows: list, row_type: type) -> pa.Table:
    """Build an Arrow table from rows of one class: structs, or tuples in field order (the
    replay loop's fast path). An empty list gives a table with 0 rows and the full schema."""
    schema = arrow_schema(row_type)
    if rows:
        if not isinstance(rows[0], tuple):
            rows = [msgspec.structs.astuple(r) for r in rows]
        columns = list(zip(*rows, strict=True))
        if len(columns) != len(schema):
            raise ValueError(
                f"{row_type.__name__} rows have {len(columns)} values, schema has {len(schema)}"
            )
    else:
        columns = [() for _ in schema]
    arrays = [pa.array(col, type=field.type) for col, field in zip(columns, schema, strict=True)]
    return pa.Table.from_arrays(arrays, schema=schema)


def table_rows(table: pa.Table, row_type: type) -> list:
    """The rows of a table of `row_type` (as `rows_to_table` or the kernel builds it), as
    instances of that class holding the values the replay computed: Arrow gives back the
    same Python values (floats as floats, lists as lists), so a row encodes to the same
    JSON whichever engine made the table."""
    names = row_type.__struct_fields__
    return [row_type(**dict(zip(names, values, strict=True))) for values in table_tuples(table)]


def table_tuples(table: pa.Table) -> list[tuple]:
    """The rows of a table as tuples in column order (the field order of its row class)."""
    return list(zip(*(column.to_pylist() for column in table.columns), strict=True))
