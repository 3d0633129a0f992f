"""The committed JSON Schemas are exactly what the record classes generate."""

from __future__ import annotations

import json
from pathlib import Path

import jsonschema

from replay import schema_documents

SCHEMAS = Path(__file__).resolve().parents[2] / "schemas"
DATA = Path(__file__).resolve().parents[1] / "data"


def test_committed_schemas_match_the_records() -> None:
    generated = schema_documents()
    committed = {p.name: p.read_bytes() for p in SCHEMAS.glob("*.schema.json")}
    missing = sorted(set(generated) - set(committed))
    stale = sorted(
        name for name in generated if name in committed and committed[name] != generated[name]
    )
    extra = sorted(set(committed) - set(generated))
    assert not (missing or stale or extra), (
        f"schemas/ drifted from the records (missing {missing}, stale {stale}, extra {extra}); "
        "run `python -m replay.schemas` and commit"
    )


def test_paper_listings_validate_against_the_ssm_schema() -> None:
    schema = json.loads((SCHEMAS / "ssm.schema.json").read_text())
    for name in ("kettle_ssm.json", "kettle_ucsm.json"):
        jsonschema.validate(json.loads((DATA / name).read_text()), schema)


def test_schema_rejects_a_wrong_type() -> None:
    schema = json.loads((SCHEMAS / "task.schema.json").read_text())
    bad = {"episode_id": "e", "device_id": "d", "goals": "Boiling"}
    try:
        jsonschema.validate(bad, schema)
    except jsonschema.ValidationError:
        return
    raise AssertionError("a string for `goals` should not validate")
