"""`bound_result`: what of a query's result the SQL page holds, with counts worked by hand."""

from __future__ import annotations

import polars as pl

from vge_analytics.store import CELL_CHARS, RESULT_BYTES, bound_result
from vge_analytics.store._page_result import CUT_MARK


def test_long_text_cells_are_cut_and_marked() -> None:
    frame = pl.DataFrame({"t": ["a" * 15, "b" * 5, None, "é" * 11], "n": [1, 2, 3, 4]})
    shown, cut = bound_result(frame, cell_chars=10)
    # "a" * 15 leaves 5 characters out, "é" * 11 one; "b" * 5 and the null stay whole
    assert shown.to_dict(as_series=False) == {
        "t": ["a" * 10 + "… [cut: 5 more characters]", "b" * 5, None, "é" * 10 + "… [cut: 1 more characters]"],
        "n": [1, 2, 3, 4],
    }  # fmt: skip
    assert (cut.cells, cut.rows) == (2, 0)
    assert cut.bytes == 0  # a tail of 5 and of 1 characters is shorter than the mark


def test_every_text_column_is_cut_and_counted_per_cell() -> None:
    frame = pl.DataFrame({"a": ["x" * 25, "y"], "b": ["z" * 30, "w" * 21]})
    shown, cut = bound_result(frame, cell_chars=20)
    assert shown["a"].to_list() == ["x" * 20 + CUT_MARK.format(5), "y"]
    assert shown["b"].to_list() == ["z" * 20 + CUT_MARK.format(10), "w" * 20 + CUT_MARK.format(1)]
    assert cut.cells == 3


def test_rows_past_the_bytes_are_left_out() -> None:
    # 100 int64 values: 800 bytes; 400 bytes hold the first 50 rows
    frame = pl.DataFrame({"n": list(range(100))})
    assert frame.estimated_size() == 800
    shown, cut = bound_result(frame, max_bytes=400)
    assert shown["n"].to_list() == list(range(50))
    assert (cut.cells, cut.rows, cut.bytes) == (0, 50, 400)
    # one byte less: 49 rows (392 bytes)
    shown, cut = bound_result(frame, max_bytes=399)
    assert (shown.height, cut.rows, cut.bytes) == (49, 51, 408)


def test_a_result_within_the_bounds_is_left_whole() -> None:
    frame = pl.DataFrame({"t": ["x" * CELL_CHARS], "n": [1]})
    shown, cut = bound_result(frame)
    assert shown.equals(frame)
    assert (cut.cells, cut.rows, cut.bytes) == (0, 0, 0)
    empty = pl.DataFrame({"t": []}, schema={"t": pl.String})
    assert bound_result(empty)[0].height == 0


def test_twenty_texts_of_five_megabytes_fit_in_a_page() -> None:
    """The issue's case, smaller: 20 cells of 5 MB (100 MB) become 20 of about 10 KB."""
    frame = pl.DataFrame({"s": ["x" * 5_000_000] * 20})
    shown, cut = bound_result(frame)
    assert shown["s"].to_list() == ["x" * CELL_CHARS + CUT_MARK.format(4_990_000)] * 20
    assert (cut.cells, cut.rows) == (20, 0)
    assert shown.estimated_size() < 250_000 < RESULT_BYTES
    assert cut.bytes == frame.estimated_size() - shown.estimated_size()
