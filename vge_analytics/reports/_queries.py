"""The named queries of the reports (`vge_analytics/sql/<name>.sql`, each with a header
saying what it computes, what it reads and its bound parameters)."""

from __future__ import annotations

from functools import cache
from importlib import resources


@cache
def query_text(name: str) -> str:
    """The text of `sql/<name>.sql`, read once per process."""
    return (resources.files("vge_analytics") / "sql" / f"{name}.sql").read_text(encoding="utf-8")


__all__ = ["query_text"]
