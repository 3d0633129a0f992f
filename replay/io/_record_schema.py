"""A record type's JSON Schema, the same bytes whatever the Python that makes it (a leaf:
`_schemas` writes `schemas/` with it, `_mcap` puts the step's schema in every MCAP file)."""

from __future__ import annotations

import inspect
from typing import Any

import msgspec


def record_schema(record: type) -> dict[str, Any]:
    """msgspec's JSON Schema of a record type, each class's description (its docstring)
    cleaned as `inspect.cleandoc` does: Python 3.13 strips a docstring's indentation when it
    compiles it, 3.11 keeps it, and the schema (in `schemas/` and in every MCAP file) must
    not depend on the Python that wrote it."""
    schema = msgspec.json.schema(record)
    for definition in schema.get("$defs", {}).values():
        if "description" in definition:
            definition["description"] = inspect.cleandoc(definition["description"])
    return schema
