"""Which run fields the dashboard offers as facets (the sidebar's filters and the `model ×
field` groupings): low-cardinality categories of how the runs were set up, never what a
run did, an address or free text."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

from replay.semantics import RUN_TOTALS

from ..store import facets

META_PREFIX = "meta_"
"""The runs table's columns of run.json's `meta` keys (PROTOCOL §7.5)."""
MAX_FACET_VALUES = 12
"""A field with more distinct values (no value counts as one) is not a facet: a picker that
long filters nothing a person can scan, and a field that names almost every run apart is an
id, not a category."""
MAX_FACET_TEXT = 40
"""Text longer than this (characters) is free text, a note or a prompt, not a category."""


def _why_not(key: str, values: Sequence[object]) -> str | None:
    """Why a run field is not a facet (None: it is one)."""
    if key in RUN_TOTALS:
        return "a total of what the run did"
    if len(values) < 2:
        return "one value: nothing to choose"
    if len(values) > MAX_FACET_VALUES:
        return f"more than {MAX_FACET_VALUES} values"
    for value in values:
        if isinstance(value, str):
            if "://" in value:
                return "an address"
            if len(value) > MAX_FACET_TEXT or "\n" in value:
                return "free text"
    return None


def offered_facets(fields: Mapping[str, Sequence[object]]) -> dict[str, list]:
    """The facets among `fields` ({`meta_<key>` column: its distinct values}, as
    `store.facets` gives them), in their order: fields of more than one and at most
    `MAX_FACET_VALUES` values, none of them an address (`://`) or free text (longer than
    `MAX_FACET_TEXT` characters, or of several lines), that are not run.json's totals
    (`replay.semantics.RUN_TOTALS`: tokens, cost, latency, episodes, ...)."""
    return {
        column: list(values)
        for column, values in fields.items()
        if _why_not(column.removeprefix(META_PREFIX), values) is None
    }


def run_facets(out: str | Path) -> dict[str, list]:
    """The run facets of OUT the dashboard offers (`offered_facets` of `store.facets`)."""
    return offered_facets(facets(out))


__all__ = ["MAX_FACET_TEXT", "MAX_FACET_VALUES", "offered_facets", "run_facets"]
