"""The Navigation page: view switches by class, with VSPS and GVPE."""


from __future__ import annotations

import polars as pl


def switch_summary(classes: pl.DataFrame, ratios: pl.DataFrame) -> pl.DataFrame:
    """One row per group: switches, the NP/PN/NN/PP shares (%), VSPS and GVPE.

    `classes` is a `switch_classes` result and `ratios` a `metrics(..., ["VSPS", "GVPE"])`
    result, both with a `group` column."""
    from ..reports import SWITCH_CLASSES

    wide = classes.pivot(
        on="switch_class", index="group", values="share", aggregate_function="first"
    )
    counts = classes.group_by("group", maintain_order=True).agg(switches=pl.col("switches").first())
    for name in SWITCH_CLASSES:
        if name not in wide.columns:
            wide = wide.with_columns(pl.lit(None, dtype=pl.Float64).alias(name))
    return (
        ratios.select("group", "VSPS", "GVPE")
        .join(counts, on="group", how="left")
        .join(
            wide.select("group", *[pl.col(c).alias(f"{c} %") for c in SWITCH_CLASSES]),
            on="group",
            how="left",
        )
        .select("group", "switches", *[f"{c} %" for c in SWITCH_CLASSES], "VSPS", "GVPE")
    )
