"""Grouping and filtering over the replay tables: column checks and the FROM/WHERE of a query.

A *scope* is what every analytics query shares: the columns to group by and the filters to
apply, resolved for one grain table (`steps`, `goals` or `episodes`). A column is looked up
in the grain table itself, then in `episodes` (joined on run_id + episode_id), then in `runs`
(joined on run_id). So `category` or `n_goals` group step metrics by the step's episode,
`meta_history` groups anything by run facet, and a step-only column such as `action_type`
can group step metrics (and nothing else).

Names are checked against the columns DuckDB reports for the views (`Store.columns`) and only
then quoted with `quote_ident`; filter *values* are always bound parameters.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from replay.io import EPISODES_TABLE, GOALS_TABLE, RUNS_TABLE, STEPS_TABLE

from .._errors import UnknownColumnError

if TYPE_CHECKING:
    from ._store import Store

GroupBy = str | Sequence[str] | None
Filters = Mapping[str, object] | None

DEFAULT_BY: tuple[str, ...] = ("run_id", "model")

_ALIAS = {"grain": "g", EPISODES_TABLE: "e", RUNS_TABLE: "r"}


def quote_ident(name: str) -> str:
    """Quote a column name as a DuckDB identifier.

    Only ever applied to names that were checked to be existing columns (see
    `Store.check_column`) or to the fixed metric names of the registry. Inside double quotes
    the parser reads everything up to the next unescaped `"` as one identifier, and every `"`
    in the name is doubled, so the name cannot end the identifier early: whatever characters a
    meta facet key holds, the result is one identifier naming that existing column, never SQL.
    """
    return '"' + name.replace('"', '""') + '"'


def parse_by(by: GroupBy) -> tuple[str, ...]:
    """Grouping columns from a list or a comma-separated string; None means the default."""
    if by is None:
        return DEFAULT_BY
    if isinstance(by, str):
        items = [b.strip() for b in by.split(",")]
        return tuple(dict.fromkeys(b for b in items if b))
    return tuple(dict.fromkeys(by))


def groupable_columns(store: Store, grain: str = EPISODES_TABLE) -> list[str]:
    """Scalar columns usable to group or filter a query on `grain`, sorted."""
    tables = [grain, EPISODES_TABLE, RUNS_TABLE] if grain != RUNS_TABLE else [RUNS_TABLE]
    cols: set[str] = set()
    for t in tables:
        cols.update(c for c in store.columns[t] if store.is_scalar(t, c))
    return sorted(cols)


def source_table(store: Store, grain: str, column: str) -> str | None:
    """Which table a column of a `grain` query comes from (grain, episodes, runs) or None."""
    order = [grain] if grain != EPISODES_TABLE else []
    order += [EPISODES_TABLE, RUNS_TABLE]
    for table in order:
        if store.has_column(table, column):
            return table
    return None


def check_columns(store: Store, columns: Sequence[str], grains: Sequence[str], what: str) -> None:
    """Raise `UnknownColumnError` unless every column resolves (to a scalar) for every grain."""
    for col in columns:
        tables = (RUNS_TABLE, EPISODES_TABLE, GOALS_TABLE, STEPS_TABLE)
        anywhere = [t for t in tables if store.has_column(t, col)]
        if not anywhere:
            known = ", ".join(groupable_columns(store, EPISODES_TABLE))
            raise UnknownColumnError(
                f"unknown {what} column {col!r}; columns of runs and episodes: {known}"
            )
        for grain in grains:
            table = source_table(store, grain, col)
            if table is None:
                raise UnknownColumnError(
                    f"{what} column {col!r} is a column of {' and '.join(anywhere)} only, so it "
                    f"cannot apply to values computed from {grain}; choose metrics computed from "
                    f"{anywhere[0]}, or a column of runs/episodes"
                )
            if not store.is_scalar(table, col):
                raise UnknownColumnError(
                    f"{what} column {col!r} holds {store.columns[table][col]} values "
                    "(lists cannot be grouped or filtered on)"
                )


@dataclass
class Scope:
    """FROM/JOIN/WHERE text and parameters of one grain query, with its key expressions."""

    grain: str
    keys: list[tuple[str, str]]
    """(qualified expression, output name) of each grouping column."""
    from_sql: str
    where_sql: str
    params: list[object] = field(default_factory=list)

    @property
    def key_select(self) -> str:
        return ", ".join(f"{expr} AS {quote_ident(name)}" for expr, name in self.keys)

    @property
    def key_group(self) -> str:
        return ", ".join(expr for expr, _ in self.keys)


def _normalise_filter(value: object) -> tuple[list[object], bool]:
    """(non-null values, whether null is allowed) of one filter."""
    if isinstance(value, (str, bytes, int, float, bool)) or value is None:
        values = [value]
    elif isinstance(value, Sequence | set | frozenset):
        values = list(value)
    else:
        values = [value]
    return [v for v in values if v is not None], any(v is None for v in values)


def _filter_condition(expr: str, sql_type: str, value: object, params: list[object]) -> str:
    """The SQL condition of one filter on `expr` (a value or several; None matches null); its
    bound parameter is appended to `params`."""
    values, allow_null = _normalise_filter(value)
    terms = []
    if values:
        # The type name comes from DuckDB's own DESCRIBE of a scalar column. One parameter
        # per value: a list of constants is a filter DuckDB hands to the table's scan (a
        # file of another run is then not read at all); `IN (SELECT unnest(?))` is a join.
        one = f"CAST(? AS {sql_type})"
        terms.append(f"{expr} IN ({', '.join([one] * len(values))})")
        params.extend(values)
    if allow_null:
        terms.append(f"{expr} IS NULL")
    return "(" + " OR ".join(terms) + ")" if terms else "FALSE"


def build_scope(
    store: Store,
    grain: str,
    by: Sequence[str],
    where: Filters = None,
    *,
    scored_only: bool = True,
) -> Scope:
    """Resolve `by` and `where` for a query on `grain` (columns must have been checked)."""
    where = dict(where or {})
    needed: dict[str, list[str]] = {EPISODES_TABLE: [], RUNS_TABLE: []}
    resolved: dict[str, str] = {}
    for col in [*by, *where]:
        table = source_table(store, grain, col)
        if table is None:  # pragma: no cover - check_columns runs first
            raise UnknownColumnError(f"column {col!r} does not apply to {grain}")
        if table == grain:
            resolved[col] = f"g.{quote_ident(col)}"
        else:
            alias = _ALIAS[table]
            if col not in needed[table]:
                needed[table].append(col)
            resolved[col] = f"{alias}.{quote_ident(col)}"

    parts = [f"{grain} AS g"]
    if needed[EPISODES_TABLE]:
        cols = ", ".join(quote_ident(c) for c in needed[EPISODES_TABLE])
        parts.append(
            "JOIN (SELECT run_id AS __run_id, episode_id AS __episode_id, "
            f"{cols} FROM episodes) AS e "
            "ON e.__run_id = g.run_id AND e.__episode_id = g.episode_id"
        )
    if needed[RUNS_TABLE]:
        cols = ", ".join(quote_ident(c) for c in needed[RUNS_TABLE])
        parts.append(
            f"LEFT JOIN (SELECT run_id AS __run_id, {cols} FROM runs) AS r ON r.__run_id = g.run_id"
        )

    conditions: list[str] = []
    params: list[object] = []
    if grain == STEPS_TABLE and scored_only:
        conditions.append("NOT g.truncated")
    for col, value in where.items():
        table = source_table(store, grain, col)
        sql_type = store.columns[table][col]
        conditions.append(_filter_condition(resolved[col], sql_type, value, params))
    return Scope(
        grain=grain,
        keys=[(resolved[c], c) for c in by],
        from_sql=" ".join(parts),
        where_sql=" AND ".join(conditions) if conditions else "TRUE",
        params=params,
    )


def run_keys_scope(store: Store, by: Sequence[str], where: Filters) -> Scope | None:
    """Scope listing every group of the runs table when all of `by` are run columns.

    Used so that a run with no row after filtering still appears, with null metrics (an empty
    group gives null, never a missing row). Only the filters on run columns apply here.
    """
    if not by or not all(store.has_column(RUNS_TABLE, c) for c in by):
        return None
    run_filters = {c: v for c, v in (where or {}).items() if store.has_column(RUNS_TABLE, c)}
    conditions: list[str] = []
    params: list[object] = []
    for col, value in run_filters.items():
        sql_type = store.columns[RUNS_TABLE][col]
        conditions.append(_filter_condition(f"g.{quote_ident(col)}", sql_type, value, params))
    return Scope(
        grain=RUNS_TABLE,
        keys=[(f"g.{quote_ident(c)}", c) for c in by],
        from_sql="runs AS g",
        where_sql=" AND ".join(conditions) if conditions else "TRUE",
        params=params,
    )


RUN_COPIES: tuple[str, ...] = ("model", "agent_kind")
"""Columns that steps, episodes and goals copy from the run header: determined by run_id."""


def run_level(store: Store, grain: str, column: str) -> bool:
    """A column whose value is fixed per run: taken from `runs`, after aggregation."""
    if column == "run_id" or not store.has_column(RUNS_TABLE, column):
        return False
    if column in RUN_COPIES:
        return True
    return source_table(store, grain, column) == RUNS_TABLE


def grouped_aggregate(
    store: Store,
    grain: str,
    by: Sequence[str],
    where: Filters,
    terms: Sequence[tuple[str, str]],
    *,
    extra_keys: Sequence[tuple[str, str]] = (),
    scored_only: bool = True,
) -> tuple[str, list]:
    """SQL of additive `terms` (aggregate expression, output name) over `grain` rows per group.

    Output columns: the `by` columns, the `extra_keys` names, the term names. Terms must be
    additive (counts, sums) because the aggregation runs in two levels when a grouping or
    filter column is fixed per run (a run facet, model, agent_kind): first per run_id and the
    row-level keys over the big table, then the few resulting rows are joined to `runs` and
    added up per group. The big table is thus never grouped by, joined to, or filtered on a
    run column row by row. Columns must have been checked (`check_columns`).
    """
    where = dict(where or {})
    run_cols = [c for c in dict.fromkeys([*by, *where]) if run_level(store, grain, c)]
    inner_by = [c for c in by if c not in run_cols]
    inner_where = {c: v for c, v in where.items() if c not in run_cols}
    outer_where = {c: v for c, v in where.items() if c in run_cols}
    inner = build_scope(store, grain, inner_by, inner_where, scored_only=scored_only)
    keys = list(inner.keys)
    if run_cols and "run_id" not in inner_by:
        keys.append(("g.run_id", "run_id"))
    key_sel = [f"{expr} AS {quote_ident(name)}" for expr, name in keys]
    key_sel += [f"{expr} AS {quote_ident(name)}" for expr, name in extra_keys]
    term_sel = [f"{expr} AS {quote_ident(name)}" for expr, name in terms]
    group = [expr for expr, _ in keys] + [expr for expr, _ in extra_keys]
    inner_sql = (
        f"SELECT {', '.join(key_sel + term_sel)} FROM {inner.from_sql} WHERE {inner.where_sql}"
    )
    if group:
        inner_sql += f" GROUP BY {', '.join(group)}"
    if not run_cols:
        return inner_sql, list(inner.params)

    params = list(inner.params)
    cols = ", ".join(quote_ident(c) for c in run_cols)
    conditions = []
    for col, value in outer_where.items():
        sql_type = store.columns[RUNS_TABLE][col]
        conditions.append(_filter_condition(f"r.{quote_ident(col)}", sql_type, value, params))
    out_keys = [f"r.{quote_ident(c)}" if c in run_cols else f"i.{quote_ident(c)}" for c in by]
    out_sel = [f"{e} AS {quote_ident(c)}" for e, c in zip(out_keys, by, strict=True)]
    out_sel += [f"i.{quote_ident(name)}" for _, name in extra_keys]
    # Added in the order of the runs: a sum of floating-point terms depends in its last bits
    # on the order of its rows, which a hash aggregate does not fix.
    out_sel += [
        f"sum(i.{quote_ident(name)} ORDER BY i.run_id) AS {quote_ident(name)}" for _, name in terms
    ]
    out_group = out_keys + [f"i.{quote_ident(name)}" for _, name in extra_keys]
    sql = (
        f"SELECT {', '.join(out_sel)} FROM ({inner_sql}) AS i "
        f"LEFT JOIN (SELECT run_id AS __run_id, {cols} FROM runs) AS r "
        "ON r.__run_id = i.run_id"
        f" WHERE {' AND '.join(conditions) if conditions else 'TRUE'}"
    )
    if out_group:
        sql += f" GROUP BY {', '.join(out_group)}"
    return sql, params


def null_safe_join(left: str, right: str, names: Sequence[str]) -> str:
    """ON condition matching two relations on key columns, nulls equal to nulls."""
    if not names:
        return "TRUE"
    return " AND ".join(
        f"{left}.{quote_ident(n)} IS NOT DISTINCT FROM {right}.{quote_ident(n)}" for n in names
    )


def order_by(names: Sequence[str], alias: str = "") -> str:
    prefix = f"{alias}." if alias else ""
    if not names:
        return ""
    return " ORDER BY " + ", ".join(f"{prefix}{quote_ident(n)} NULLS LAST" for n in names)


__all__ = [
    "DEFAULT_BY",
    "Filters",
    "GroupBy",
    "Scope",
    "build_scope",
    "check_columns",
    "groupable_columns",
    "grouped_aggregate",
    "null_safe_join",
    "order_by",
    "parse_by",
    "quote_ident",
    "run_keys_scope",
    "run_level",
    "source_table",
]
