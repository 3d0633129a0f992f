"""The committed JSON Schemas are exactly what the record classes generate."""

from __future__ import annotations

import json
from pathlib import Path

import jsonschema
import msgspec

from replay.io import record_schema, schema_documents

SCHEMAS = Path(__file__).resolve().parents[3] / "schemas"
DATA = Path(__file__).resolve().parents[2] / "data"


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


class _Indented(msgspec.Struct):
    """First line.

    Second paragraph, indented in the source.
        Deeper still."""

    x: int


def test_a_class_description_is_its_docstring_cleaned_whatever_the_python() -> None:
    """Python 3.11 keeps a docstring's indentation, 3.13 strips it as it compiles: the schema
    holds the cleaned form either way, so the files are the same bytes from both."""
    (definition,) = record_schema(_Indented)["$defs"].values()
    assert definition["description"] == (
        "First line.\n\nSecond paragraph, indented in the source.\n    Deeper still."
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


def test_replay_outputs_validate_against_their_schemas(tmp_path: Path) -> None:
    import gzip
    import shutil

    from replay import replay_runs

    logs = Path(__file__).resolve().parents[3] / "logs"
    run = tmp_path / "run"
    shutil.copytree(logs / "runs" / "sim-human", run)
    lines = gzip.decompress((run / "episodes.jsonl.gz").read_bytes()).splitlines()[:3]
    (run / "episodes.jsonl.gz").unlink()
    (run / "episodes.jsonl").write_bytes(
        b"\n".join(lines + [b'{"episode_id": "nope", "steps": []}', b"{oops"]) + b"\n"
    )
    out = tmp_path / "out"
    manifest = replay_runs([run], logs / "bench", out, progress=False)
    assert manifest.quarantined == 2
    jsonschema.validate(
        json.loads((out / "manifest.json").read_text()),
        json.loads((SCHEMAS / "manifest.schema.json").read_text()),
    )
    quarantine_schema = json.loads((SCHEMAS / "quarantine.schema.json").read_text())
    records = [json.loads(line) for line in (out / "quarantine.jsonl").read_text().splitlines()]
    assert [r["kind"] for r in records] == ["unknown_episode", "malformed_json"]
    for record in records:
        jsonschema.validate(record, quarantine_schema)
