"""`vge errors OUT`: error taxonomy (share of errors, the paper's pie) and switch classes."""

from __future__ import annotations

from typing import TYPE_CHECKING

import typer

from .. import reports, store
from ._bounds import command_limits
from ._options import (
    by_option,
    format_option,
    memory_limit_option,
    out_argument,
    parse_where,
    timeout_option,
    where_option,
)
from ._output import emit_sections
from ._selection import check_where

if TYPE_CHECKING:
    import polars as pl


def _wide(df: pl.DataFrame, by: list[str], index: list[str], value: str) -> pl.DataFrame:
    """One column per group (its values joined by '/'), one row per index entry."""
    import polars as pl

    keyed = df.with_columns(
        pl.concat_str(
            [pl.col(c).cast(pl.String).fill_null("null") for c in by], separator="/"
        ).alias("__group")
        if by
        else pl.lit("all").alias("__group")
    )
    return keyed.pivot(on="__group", index=index, values=value, maintain_order=True)


def errors_command(
    out: str = out_argument(),
    by: str = by_option("run_id", "Group by these columns (default: run_id)."),
    where: list[str] = where_option(),
    fmt: str = format_option(),
    timeout: float = timeout_option(),
    memory_limit: str = memory_limit_option(what="each query"),
) -> None:
    """Error taxonomy (share of errors, counts) and switch classes per run.

    The seven error types and three error groups as shares of all errors (the paper's pie)
    with counts, and the NP/PN/NN/PP classes of successful view switches.
    """
    import polars as pl

    with command_limits(out, timeout, memory_limit):
        reports.check_format(fmt)
        by_cols = list(store.parse_by(by))
        filters = parse_where(where)
        check_where(out, filters, where)
        types = reports.error_distribution(out, by_cols, filters)
        groups = reports.groups_of(types, by_cols)
        switches = reports.switch_classes(out, by_cols, filters)
        if fmt in ("json", "csv"):
            sections = {"error_types": types, "error_groups": groups, "switch_classes": switches}
        else:
            labelled = types.with_columns(
                error_type=pl.col("error_type").replace_strict(reports.ERROR_LABELS)
            )
            sections = {
                "error types: share of errors (%)": _wide(
                    labelled, by_cols, ["error_group", "error_type"], "share"
                ),
                "error types: count": _wide(
                    labelled, by_cols, ["error_group", "error_type"], "count"
                ),
                "error groups: share of errors (%)": _wide(
                    groups, by_cols, ["error_group"], "share"
                ),
                "switch classes: share of classified switches (%)": _wide(
                    switches, by_cols, ["switch_class"], "share"
                ),
                "switch classes: count": _wide(switches, by_cols, ["switch_class"], "count"),
            }
        emit_sections(sections, fmt, fixed=True)


def register(app: typer.Typer) -> None:
    app.command("errors")(errors_command)
