"""Checking a metric's SQL before it is used: each expression must bind, over its grain
table, as one aggregate giving numbers.

DuckDB binds (without running) `SELECT g.run_id, (<expression>) FROM <grain> AS g GROUP BY
g.run_id` over empty tables with the replay's output schema (`replay.arrow_schema`), the
shape in which `_metrics.compose` uses the expression. That catches an unknown column, a
syntax error, a column used outside an aggregate, an expression that is not a number, and
text that is not one expression (a `;`, extra columns). The connection doing it is locked
like the store's (no file access, no extensions, settings final), so binding a file
reference fails instead of reading the file.

A problem is reported at the line of the file DuckDB points to (its `LINE n:`), else at the
expression's first line.
"""

from __future__ import annotations

import re
import threading

import duckdb
import pyarrow as pa

import replay

from ._metric_file import Metric, Problem
from ._store import NUMERIC_TYPES

_LINE = re.compile(r"\bLINE (\d+):")

_lock = threading.Lock()
_connection: list[duckdb.DuckDBPyConnection] = []
_empty: list[pa.Table] = []


def _schema_connection() -> duckdb.DuckDBPyConnection:
    """An in-memory DuckDB with empty `steps`, `episodes`, `goals` tables (made once)."""
    with _lock:
        if not _connection:
            # Binding needs no worker threads and no memory to speak of.
            con = duckdb.connect(":memory:", config={"threads": 1, "memory_limit": "64MB"})
            for table in replay.TABLE_ROWS:  # steps, episodes, goals
                empty = replay.arrow_schema(replay.TABLE_ROWS[table]).empty_table()
                _empty.append(empty)
                con.from_arrow(empty).create_view(table)
            con.execute("SET enable_external_access = false")
            con.execute("SET autoinstall_known_extensions = false")
            con.execute("SET autoload_known_extensions = false")
            con.execute("SET lock_configuration = true")
            _connection.append(con)
        return _connection[0].cursor()


def bind_query(grain: str, expression: str) -> str:
    """The statement that binds `expression` as `_metrics.compose` uses it (the expression
    starts on line 2; `grain` is one of the three fixed table names)."""
    return (
        "SELECT g.run_id AS __group, (\n"
        + expression
        + "\n) AS __value FROM "
        + grain
        + " AS g GROUP BY g.run_id"
    )


def _first_lines(exc: BaseException) -> tuple[str, int | None]:
    """DuckDB's message in one line (with its candidate columns), and its `LINE n`."""
    text = str(exc).strip()
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    message = lines[0] if lines else type(exc).__name__
    for extra in lines[1:]:
        if extra.startswith("Candidate bindings"):
            message += f" ({extra[0].lower()}{extra[1:]})"
    found = _LINE.search(text)
    return message, int(found.group(1)) if found else None


def check_expression(metric: Metric, part: str) -> Problem | None:
    """The problem with the metric's numerator or denominator (`part`), or None."""
    expression = metric.numerator if part == "numerator" else metric.denominator
    first = metric.numerator_line if part == "numerator" else metric.denominator_line
    last = first + expression.count("\n")

    def problem(message: str, query_line: int | None = None) -> Problem:
        line = first if query_line is None else min(max(first + query_line - 2, first), last)
        return Problem(metric.source, line, f"the {part} {message}")

    query = bind_query(metric.grain, expression)
    cursor = _schema_connection()
    try:
        try:
            statements = cursor.extract_statements(query)
        except duckdb.Error as exc:
            message, line = _first_lines(exc)
            return problem(f"is not valid SQL: {message}", line)
        if len(statements) != 1:
            return problem("must be one SQL expression (it holds a ';')")
        relation = cursor.sql(query)
        columns, types = relation.columns, [str(t) for t in relation.types]
    except duckdb.Error as exc:
        message, line = _first_lines(exc)
        return problem(f"does not bind over {metric.grain}: {message}", line)
    finally:
        cursor.close()
    if columns != ["__group", "__value"]:
        return problem("must be one SQL expression (it adds columns)")
    kind = types[1].upper()
    if kind not in NUMERIC_TYPES and not kind.startswith("DECIMAL"):
        return problem(f"gives {types[1]} values, not numbers (it must be a count or a sum)")
    return None


def check_metric(metric: Metric) -> list[Problem]:
    """Every binding problem of a parsed metric (its numerator and its denominator)."""
    found = [check_expression(metric, part) for part in ("numerator", "denominator")]
    return [p for p in found if p is not None]


__all__ = ["bind_query", "check_expression", "check_metric"]
