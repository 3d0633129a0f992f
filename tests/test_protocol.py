"""docs/PROTOCOL.md against the code: the document cannot drift.

The vocabularies the protocol lists (table columns with their types, feedback kinds, parse
details, error types and groups, error details, switch classes, terminations, quarantine
kinds, views, MCAP topics) must be exactly the ones the code declares, in the same order; every
section has its anchor; every "PROTOCOL §n" cited anywhere in the repository, and every link
to a section, names a section that exists.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

import replay
from replay.io._manifest import _RUN_COLUMNS
from replay.io._mcap import SCHEMA_NAMES, TOPICS
from replay.semantics import FEEDBACK_SEVERITY, PARAMETER_CODES
from replay.semantics import _vocab as vocab
from tests.test_self_contained import repository_files

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "PROTOCOL.md"
TEXT = DOC.read_text(encoding="utf-8")
ANCHOR = re.compile(r'<a id="(s\d+(?:-\d+)*)"></a>')
CODE = re.compile(r"`([^`\n]+)`")


def section(anchor: str) -> str:
    """The text of a section, from its anchor to the next anchor."""
    start = TEXT.index(f'<a id="{anchor}"></a>')
    following = ANCHOR.search(TEXT, start + 1)
    return TEXT[start : following.start() if following else len(TEXT)]


def table(anchor: str, number: int = 0) -> list[list[str]]:
    """The body rows of a section's table (the first unless `number` says), cells stripped."""
    blocks: list[list[str]] = [[]]
    for line in section(anchor).splitlines():
        if line.startswith("|"):
            blocks[-1].append(line)
        elif blocks[-1]:
            blocks.append([])
    lines = blocks[number] if number < len(blocks) else []
    assert len(lines) > 2 and set(lines[1]) <= set("|-: "), f"no table in §{anchor}"
    return [[cell.strip() for cell in line.strip("|").split(" | ")] for line in lines[2:]]


def names(anchor: str, column: int = 0) -> list[str]:
    return [row[column].strip("`") for row in table(anchor)]


def code_words(*anchors: str) -> set[str]:
    return {word for anchor in anchors for word in CODE.findall(section(anchor))}


_TYPES = {
    "string": "str",
    "int64": "int",
    "double": "float",
    "bool": "bool",
    "list<item: string>": "list[str]",
    "list<item: int64>": "list[int]",
}


def documented(field) -> tuple[str, str]:
    return field.name, _TYPES[str(field.type)] + ("?" if field.nullable else "")


@pytest.mark.parametrize(
    ("name", "anchor"), [("steps", "s7-2"), ("episodes", "s7-3"), ("goals", "s7-4")]
)
def test_table_columns_and_types(name: str, anchor: str) -> None:
    declared = [documented(f) for f in replay.arrow_schema(replay.TABLE_ROWS[name])]
    assert [(row[0].strip("`"), row[1]) for row in table(anchor)] == declared


def test_runs_table_columns() -> None:
    assert [(row[0].strip("`"), row[1]) for row in table("s7-5")] == [
        documented(f) for f in _RUN_COLUMNS
    ]


def test_feedback_kinds_and_severities() -> None:
    assert names("s3-6") == list(vocab.FEEDBACK_KINDS)
    assert dict(zip(names("s3-6"), names("s3-6", 1), strict=True)) == FEEDBACK_SEVERITY


def test_parameter_codes() -> None:
    # §2's second table: an interaction's codes, "0 first, 1 second, ..." in one cell.
    codes = {row[0].strip("`").lower(): row[2] for row in table("s2", 1)}
    assert codes == {
        action: ", ".join(f"{i} {meaning}" for i, meaning in enumerate(meanings))
        for action, meanings in PARAMETER_CODES.items()
    }


def test_parse_details() -> None:
    assert names("s2") == list(vocab.PARSE_DETAILS)


def test_error_types_and_groups() -> None:
    assert [(row[0].strip("`"), row[1]) for row in table("s5-2")] == list(
        vocab.ERROR_GROUPS.items()
    )


def test_error_details() -> None:
    # Every detail code a step can carry: parse details, validity details (the reasons of
    # invalid_action feedback), and the two of the classifier.
    assert set(vocab.ERROR_DETAILS) <= code_words("s2", "s5-2")
    assert set(vocab.INVALID_DETAILS) - set(vocab.PARSE_DETAILS) <= code_words("s3-2")


def test_switch_classes_terminations_quarantine_kinds() -> None:
    assert set(vocab.SWITCH_CLASSES) <= code_words("s5-3")
    assert names("s3-5") == list(vocab.TERMINATIONS)
    assert names("s7-6") == list(replay.QUARANTINE_KINDS)


def test_views_and_their_order() -> None:
    listed = [w for w in CODE.findall(section("s3-1")) if w in vocab.VIEW_RANK]
    assert tuple(dict.fromkeys(listed)) == vocab.VIEWS
    assert " ".join(vocab.VIEW_ORDER) in " ".join(section("s4-3").split())


def test_mcap_topics() -> None:
    rows = table("s7-8")
    assert [row[0].strip("`") for row in rows] == list(TOPICS)
    assert {row[0].strip("`"): row[1].strip("`") for row in rows} == {
        topic: SCHEMA_NAMES[topic] for topic in TOPICS
    }


def test_every_heading_has_its_anchor() -> None:
    lines = TEXT.splitlines()
    anchors = ANCHOR.findall(TEXT)
    assert len(anchors) == len(set(anchors))
    for i, line in enumerate(lines):
        match = re.match(r"#{2,3} §(\d+(?:\.\d+)*) ", line)
        if line.startswith(("## ", "### ")):
            assert match, f"heading without a section number: {line}"
            expected = "s" + match.group(1).replace(".", "-")
            assert lines[i - 1] == f'<a id="{expected}"></a>', line
    for number in range(1, 10):
        assert f"s{number}" in anchors


def test_every_citation_names_a_section() -> None:
    anchors = set(ANCHOR.findall(TEXT))
    cited = re.compile(r"PROTOCOL §(\d+(?:\.\d+)*)")
    linked = re.compile(r"PROTOCOL\.md#(s[\d-]+)")
    checked = 0
    for path in repository_files():
        if path.suffix not in {".py", ".md", ".json", ".sql", ".toml", ".sh"}:
            continue
        text = path.read_text(encoding="utf-8", errors="replace")
        for number in cited.findall(text):
            assert "s" + number.replace(".", "-") in anchors, (path, number)
            checked += 1
        for anchor in linked.findall(text):
            assert anchor in anchors, (path, anchor)
    assert checked > 100  # the code cites the protocol throughout
