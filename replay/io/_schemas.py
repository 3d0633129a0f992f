"""JSON Schemas of every input and output record, generated from the record classes.

`python -m replay.schemas [DIR]` (re)writes `schemas/`; a test fails when the committed files
differ from what the classes generate, so the schemas cannot drift.
"""

from __future__ import annotations

from pathlib import Path

import msgspec

from ..semantics import INPUT_RECORDS, OUTPUT_RECORDS
from ._durable import write_atomic
from ._manifest import ManifestFile
from ._quarantine import QuarantineRecord
from ._record_schema import record_schema

OTHER_OUTPUTS: dict[str, type] = {"manifest": ManifestFile, "quarantine": QuarantineRecord}
"""`OUT/manifest.json` and a line of `OUT/quarantine.jsonl`."""


def schema_documents() -> dict[str, bytes]:
    """File name -> pretty JSON bytes, for every record type."""
    docs: dict[str, bytes] = {}
    records = {
        **INPUT_RECORDS,
        **{f"{k}_row": v for k, v in OUTPUT_RECORDS.items()},
        **OTHER_OUTPUTS,
    }
    for name, record in records.items():
        schema = {
            "$schema": "https://json-schema.org/draft/2020-12/schema",
            "title": name,
            **record_schema(record),
        }
        docs[f"{name}.schema.json"] = (
            msgspec.json.format(msgspec.json.encode(schema), indent=2) + b"\n"
        )
    return docs


def write_schemas(directory: str | Path) -> list[Path]:
    """Write every schema into `directory`; returns the paths written."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    written = []
    for name, data in sorted(schema_documents().items()):
        path = directory / name
        write_atomic(path, data)
        written.append(path)
    return written
