"""Checking a metric's SQL before it is used: each expression must bind, over its grain
table, as one aggregate giving numbers.

DuckDB binds (without running) `SELECT g.run_id, (<expression>) FROM <grain> AS g GROUP BY
g.run_id` over empty tables with the replay's output schema (`replay.arrow_schema`), the
shape in which `store.ratio_query` uses the expression. That catches an unknown column, a
syntax error, a column used outside an aggregate, an expression that is not a number, and
text that is not one expression (a `;`, extra columns). The connection doing it is locked
like the store's (`_locked`: no file access, a read-only catalog, no extensions, settings
final), so binding a file reference fails instead of reading the file. DuckDB refuses an
expression nested more than `MAX_EXPRESSION_DEPTH` levels, which bounds the parse tree read
below (and the recursion that reads it).

Then the expression must be additive (its value over a union of rows is the sum of its
values over the parts), because the metric's terms are added across runs, groups and the
resampled episodes of `compare`. Read from DuckDB's own parse tree (`json_serialize_sql`),
the expression must be a sum or a count (no DISTINCT), or built from them with `+`, `-`, a
constant factor, a cast, or `coalesce(..., 0)`; what is inside an aggregate is free. The tree
must also be one expression: text that closes the parenthesis around it and goes on with a
second query (`UNION`, `EXCEPT`, `INTERSECT`) binds in the shape above, and is refused here.

A problem is reported at the line of the file DuckDB points to (its `LINE n:`), else at the
expression's first line.
"""

from __future__ import annotations

import json
import re
import threading
from typing import Any

import duckdb
import pyarrow as pa

import replay
from replay.io import TABLE_ROWS

from ..store import NUMERIC_TYPES, locked_connection, register_all
from ._file import Metric, Problem

_LINE = re.compile(r"\bLINE (\d+):")
_DEPTH = "Max expression depth limit"

MAX_EXPRESSION_DEPTH = 100
"""Levels of nesting (operators, calls, parentheses) a metric expression may have: far above
any metric (the built-ins nest a few levels), far below what reading its parse tree in
Python could not follow (DuckDB's own default is 1,000)."""

_lock = threading.Lock()
_connection: list[duckdb.DuckDBPyConnection] = []
_EMPTY: dict[str, pa.Table] = {}


def _schema_connection() -> duckdb.DuckDBPyConnection:
    """A cursor on a locked DuckDB (made once) with empty `steps`, `episodes`, `goals`."""
    with _lock:
        if not _connection:
            for table, row_type in TABLE_ROWS.items():  # steps, episodes, goals
                _EMPTY[table] = replay.arrow_schema(row_type).empty_table()
            # Binding needs no worker threads; serializing the parse tree of a long
            # expression (a list of 100,000 constants) takes tens of MB. The depth limit is
            # given at start: so set, it holds for every cursor (SET would hold for one).
            config = {"threads": "1", "memory_limit": "256MB"}
            _connection.append(
                locked_connection({**config, "max_expression_depth": str(MAX_EXPRESSION_DEPTH)})
            )
        cursor = _connection[0].cursor()
    register_all(cursor, _EMPTY)
    return cursor


def bind_query(grain: str, expression: str) -> str:
    """The statement that binds `expression` as `store.ratio_query` uses it (the expression
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
            if _DEPTH in message:  # DuckDB's advice (SET max_expression_depth) is not for users
                return problem(
                    f"nests more than {MAX_EXPRESSION_DEPTH} levels deep (operators, calls, "
                    "parentheses)"
                )
            return problem(f"is not valid SQL: {message}", line)
        if len(statements) != 1:
            return problem("must be one SQL expression (it holds a ';')")
        try:
            relation = cursor.sql(query)
            columns, types = relation.columns, [str(t) for t in relation.types]
        except duckdb.Error as exc:
            message, line = _first_lines(exc)
            return problem(f"does not bind over {metric.grain}: {message}", line)
        if columns != ["__group", "__value"]:
            return problem("must be one SQL expression (it adds columns)")
        kind = types[1].upper()
        if kind not in NUMERIC_TYPES and not kind.startswith("DECIMAL"):
            return problem(f"gives {types[1]} values, not numbers (it must be a count or a sum)")
        try:
            node = _parsed(cursor, expression)
        except duckdb.Error as exc:
            return problem(f"cannot be checked: {_first_lines(exc)[0]}")
    finally:
        cursor.close()
    if node.get("type") != "SELECT_NODE":  # it closed the parenthesis: `...) UNION SELECT (...`
        return problem(f"must be one SQL expression (it adds {node.get('setop_type')})")
    why = not_additive(node["select_list"][0])
    if why is not None:
        return problem(
            f"is not additive: {why} (the terms are added across runs, groups and resampled "
            "episodes; write a mean as a sum in the numerator over a count in the denominator)"
        )
    return None


_ADDITIVE = frozenset({"sum", "fsum", "sumkahan", "kahan_sum", "count", "count_star"})
"""Aggregates whose value over a union of rows is the sum of their values over the parts."""


def _arguments(node: dict[str, Any]) -> list[dict[str, Any]]:
    """A function's argument expressions (each wrapped with its name in the tree)."""
    return [a.get("expression", a) for a in node.get("arguments") or []]


def _constant(node: dict[str, Any]) -> dict[str, Any] | None:
    """The constant a node is (through casts and a sign), or None."""
    while True:
        kind = node.get("class")
        if kind == "CONSTANT":
            return node
        if kind == "CAST":
            node = node["child"]
        elif kind == "FUNCTION" and node.get("function_name") == "-" and len(_arguments(node)) == 1:
            node = _arguments(node)[0]
        else:
            return None


def _is_zero(node: dict[str, Any]) -> bool:
    constant = _constant(node)
    text = None if constant is None else (constant.get("literal") or {}).get("text")
    try:
        return text is not None and float(text) == 0
    except ValueError:
        return False


def not_additive(node: dict[str, Any]) -> str | None:
    """Why the expression (a node of DuckDB's parse tree) is not additive, or None."""
    kind = node.get("class")
    if kind == "FUNCTION":
        name = str(node.get("function_name", "")).lower()
        args = _arguments(node)
        if not node.get("is_operator"):
            if name not in _ADDITIVE:
                return f"{name}(...) is not a sum or a count"
            if node.get("distinct"):
                return f"{name}(DISTINCT ...) is not a sum or a count of rows"
            return None
        if name in ("+", "-"):
            return next((why for why in map(not_additive, args) if why), None)
        if name == "*" and len(args) == 2:
            factors = [a for a in args if _constant(a) is None]
            if len(factors) == 1:
                return not_additive(factors[0])
        return f"'{name}' applied to aggregates is not a sum of them"
    if kind == "CAST":
        return not_additive(node["child"])
    if kind == "OPERATOR" and node.get("type") == "OPERATOR_COALESCE":
        children = node.get("children") or []
        if len(children) == 2 and _is_zero(children[1]):
            return not_additive(children[0])
        return "coalesce(...) other than coalesce(aggregate, 0) is not a sum"
    if kind == "SUBQUERY":
        return "a subquery outside an aggregate is not a sum or a count"
    if kind == "CONSTANT":
        return "a constant outside an aggregate is not a sum or a count"
    return f"{str(node.get('type', kind)).lower()} around the aggregates is not a sum of them"


def _parsed(cursor: duckdb.DuckDBPyConnection, expression: str) -> dict[str, Any]:
    """The parse tree of `SELECT (<expression>)`: the node of its one statement (it bound,
    so it parses)."""
    text = cursor.execute(
        "SELECT json_serialize_sql(?::VARCHAR)", ["SELECT (\n" + expression + "\n)"]
    ).fetchall()[0][0]
    return json.loads(text)["statements"][0]["node"]


def check_metric(metric: Metric) -> list[Problem]:
    """Every binding problem of a parsed metric (its numerator and its denominator)."""
    found = [check_expression(metric, part) for part in ("numerator", "denominator")]
    return [p for p in found if p is not None]


__all__ = ["bind_query", "check_expression", "check_metric", "not_additive"]
