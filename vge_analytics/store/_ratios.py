"""The statement behind every metric: sums over several grain tables per group, joined on the
group keys, and their ratios (PROTOCOL §6).

One statement per call: for each grain the ratios need (episodes, steps, goals), one
aggregate over that table (`grouped_aggregate`: joined to episodes/runs only when a grouping
or filter column lives there) computing every ratio's numerator and denominator; the
aggregates are joined on the group keys and each ratio is `scale * numerator /
nullif(denominator, 0)`, so an empty group gives null and never a division error. Groups come
out sorted by the group columns. The metrics room says which ratios (its definitions); the
whole text is composed here.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Protocol

from replay.io import GRAINS

from ._scope import (
    Filters,
    check_columns,
    grouped_aggregate,
    null_safe_join,
    order_by,
    quote_ident,
    run_keys_scope,
)
from ._store import Store


class Ratio(Protocol):
    """A ratio of two SQL aggregates over the rows of one grain table (a metric)."""

    @property
    def name(self) -> str: ...
    @property
    def grain(self) -> str: ...
    @property
    def numerator(self) -> str: ...
    @property
    def denominator(self) -> str: ...
    @property
    def scale(self) -> float: ...


def term_name(ratio: Ratio, part: str) -> str:
    """The column of a ratio's numerator (`part` "num") or denominator ("den")."""
    return f"{ratio.name}:{part}"


def _term(ratio: Ratio, part: str) -> str:
    return quote_ident(term_name(ratio, part))


def _grain_query(
    store: Store,
    grain: str,
    ratios: list[Ratio],
    by: Sequence[str],
    where: Filters,
    cached: str | None = None,
) -> tuple[str, list]:
    if cached is not None:  # the episodes' terms, added up (`_cache`)
        from ._cache import cached_terms

        return grouped_aggregate(store, cached, by, where, cached_terms(ratios))
    return grouped_aggregate(store, grain, by, where, ratio_terms(ratios))


def ratio_terms(ratios: Sequence[Ratio]) -> list[tuple[str, str]]:
    """(aggregate expression, column) of each numerator and denominator of `ratios` over their
    grain's rows, an empty sum as 0 (`grouped_aggregate`'s terms)."""
    # Each expression on lines of its own, as the metric check binds it: a trailing `--`
    # comment in a metric file ends with its line.
    terms = []
    for r in ratios:
        terms.append((f"coalesce(\n{r.numerator}\n, 0)", term_name(r, "num")))
        terms.append((f"coalesce(\n{r.denominator}\n, 0)", term_name(r, "den")))
    return terms


def _keys(
    store: Store, by: Sequence[str], where: Filters, grains: list[str]
) -> tuple[str, list[object]]:
    """The `keys` CTE: every group, from the runs table when all of `by` are its columns (a
    run with no row left after filtering still shows, with null ratios)."""
    if not by:
        return "SELECT 1 AS __one", []
    keys_cols = ", ".join(quote_ident(n) for n in by)
    runs_scope = run_keys_scope(store, by, where)
    if runs_scope is None:
        return " UNION ".join(f"SELECT {keys_cols} FROM agg_{g}" for g in grains), []
    sql = (
        f"SELECT DISTINCT {runs_scope.key_select} FROM {runs_scope.from_sql} "
        f"WHERE {runs_scope.where_sql}"
    )
    # Groups present in the data but missing from runs (should not happen) still show.
    sql += "".join(f" UNION SELECT {keys_cols} FROM agg_{g}" for g in grains)
    return sql, list(runs_scope.params)


def ratio_query(
    store: Store,
    by: Sequence[str],
    ratios: Sequence[Ratio],
    where: Filters = None,
    *,
    terms: bool = False,
    cached: Mapping[str, str] | None = None,
) -> tuple[str, list]:
    """The SQL text and bound parameters computing `ratios` per group of `by` (columns of
    runs, episodes, or of the grain tables; checked here), filtered by `where`.

    With `terms=True` the result holds each ratio's numerator and denominator
    (`"<name>:num"`, `"<name>:den"`) instead of its value. `cached`: {grain: table} of the
    grains read from their cached per-episode terms (`_cache.cached_store`)."""
    grains = [g for g in GRAINS if any(r.grain == g for r in ratios)]
    check_columns(store, [*by, *(where or {})], grains, "grouping/filter")
    ctes: list[str] = []
    params: list[object] = []
    for grain in grains:
        chosen = [r for r in ratios if r.grain == grain]
        sql, p = _grain_query(store, grain, chosen, by, where, (cached or {}).get(grain))
        ctes.append(f"agg_{grain} AS ({sql})")
        params.extend(p)
    keys_sql, keys_params = _keys(store, by, where, grains)
    ctes.append(f"keys AS ({keys_sql})")
    params.extend(keys_params)

    select = [f"k.{quote_ident(n)}" for n in by]
    for r in ratios:
        src = f"agg_{r.grain}"
        num, den = f"{src}.{_term(r, 'num')}", f"{src}.{_term(r, 'den')}"
        if terms:
            select.append(f"coalesce({num}, 0) AS {_term(r, 'num')}")
            select.append(f"coalesce({den}, 0) AS {_term(r, 'den')}")
        else:
            select.append(f"CAST(? AS DOUBLE) * {num} / nullif({den}, 0) AS {quote_ident(r.name)}")
    joins = "".join(
        f" LEFT JOIN agg_{g} ON {null_safe_join('k', f'agg_{g}', list(by))}" for g in grains
    )
    sql = (
        "WITH "
        + ", ".join(ctes)
        + f" SELECT {', '.join(select)} FROM keys AS k{joins}"
        + order_by(list(by), "k")
    )
    if not terms:
        params.extend(r.scale for r in ratios)
    return sql, params


__all__ = ["Ratio", "ratio_query", "ratio_terms", "term_name"]
