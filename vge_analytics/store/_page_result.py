"""What of a query's result a page holds: the SQL page's rows cut to a bounded size.

The query process cuts its rows before it sends them (`bound_result`): each text cell at
`CELL_CHARS` characters, then the whole at `RESULT_BYTES`, so the dashboard's server never
holds more of a result than that, whatever the query makes (`SELECT repeat('x', 50000000)
FROM range(20)` grew the server by 8 GB, and Streamlit refused the page's message). What was
cut is counted (`ResultCut`) for the page's caption.
"""

from __future__ import annotations

from dataclasses import dataclass

import polars as pl

RESULT_BYTES = 32 << 20
"""Bytes of a result the query process sends the server (as polars counts them, after the
cells are cut): the rows past it are left out."""
CELL_CHARS = 10_000
"""Characters of a text cell the SQL page shows: a longer one is cut there and ends with
`CUT_MARK`."""
CUT_MARK = "… [cut: {} more characters]"
"""What ends a cut cell (the number of characters left out)."""


@dataclass(frozen=True)
class ResultCut:
    """What `bound_result` left out of the rows it was given."""

    cells: int = 0
    """Text cells cut at `CELL_CHARS` characters."""
    rows: int = 0
    """Rows left out past `RESULT_BYTES` (after the cut cells)."""
    bytes: int = 0
    """Bytes left out, the cells' tails and the rows together (as polars counts them)."""


def bound_result(
    frame: pl.DataFrame, *, cell_chars: int = CELL_CHARS, max_bytes: int = RESULT_BYTES
) -> tuple[pl.DataFrame, ResultCut]:
    """The rows as a page can show them: each text cell longer than `cell_chars` cut there
    and marked (`CUT_MARK`), then the first rows that fit in `max_bytes`. Nested values
    (lists, structs) and binary ones are not cut: they count whole against `max_bytes`."""
    before, rows = frame.estimated_size(), frame.height
    texts = [name for name, dtype in frame.schema.items() if dtype == pl.String]
    cells = 0
    if texts and rows:
        long = pl.sum_horizontal(pl.col(c).str.len_chars().gt(cell_chars) for c in texts)
        cells = int(frame.select(long.sum()).item() or 0)
    if cells:
        frame = frame.with_columns(_cut_text(pl.col(c), cell_chars).alias(c) for c in texts)
    if frame.estimated_size() > max_bytes:
        fits, over = 0, rows  # the first `fits` rows fit, the first `over` do not
        while over - fits > 1:
            middle = (fits + over) // 2
            if frame.head(middle).estimated_size() <= max_bytes:
                fits = middle
            else:
                over = middle
        frame = frame.head(fits)
    left_out = max(0, before - frame.estimated_size())  # a short cut may add its mark's bytes
    return frame, ResultCut(cells, rows - frame.height, left_out)


def _cut_text(text: pl.Expr, chars: int) -> pl.Expr:
    length = text.str.len_chars()
    head, tail = CUT_MARK.split("{}")
    marked = pl.concat_str(
        text.str.slice(0, chars), pl.lit(head), (length - chars).cast(pl.String), pl.lit(tail)
    )
    return pl.when(length > chars).then(marked).otherwise(text)


__all__ = ["CELL_CHARS", "CUT_MARK", "RESULT_BYTES", "ResultCut", "bound_result"]
