"""A query's result is made a polars frame under the command's cap only when there is room
for it (`_sql.polars_frame`): polars aborts the process where an allocation fails, so a
result too large for what is left ends with the one-line memory error instead."""

from __future__ import annotations

import os
import resource
import signal
import subprocess
import sys
from pathlib import Path

import duckdb
import polars as pl
import pyarrow as pa
import pytest

import vge_analytics as va
from tests.vge_analytics.store.test_scan_counts import _steps, _with_steps
from vge_analytics.store import SqlLimits, _limits, _sql, open_store, run_query


def _vge(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    """`vge ARGS` in a fresh process (the module's own `POLARS_FROM_BYTES`: DuckDB's query
    counts a small OUT)."""
    return subprocess.run(
        [sys.executable, "-m", "vge_analytics.cli", *args],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=cwd,
        env={**os.environ, "PYTHONPATH": str(Path(va.__file__).parents[1])},
    )


def test_a_result_past_the_cap_ends_in_one_line_not_an_abort(pair_out: Path, tmp_path: Path):
    # A million error types in run B: DuckDB's count fits in 128 MB and its Arrow result is
    # 31 MB, but the query leaves some 14 MB under the process's cap, and polars' frame of
    # it takes 70 MB more (a view per string): at BASE polars aborted the process (SIGABRT).
    out = _with_steps(pair_out, tmp_path / "out", _steps(1_000_000, pl.format("e{}", "n")))
    stopped = _vge("errors", str(out), "--memory-limit", "128MB", cwd=tmp_path)
    assert stopped.returncode == 1, stopped.stderr[-2000:]
    assert stopped.stdout == ""
    assert stopped.stderr.splitlines() == [
        f"error: {out}: a query needed more memory than its limit (128 MB in memory, 256 MB "
        "on disk) and was stopped (--memory-limit sets the limit)"
    ]
    answered = _vge("errors", str(out), "-f", "csv", cwd=tmp_path)  # the default limit
    assert answered.returncode == 0, answered.stderr[-2000:]
    assert "Traceback" not in answered.stderr
    lines = answered.stdout.splitlines()
    assert lines[:2] == ["# error_types", "run_id,error_group,error_type,count,share"]
    # run A's 16 errors, 2 of them invalid coordinates; B's million types are none of ours
    assert {"A,grounding,invalid_coord,2,12.5", "A,execution,action_error,14,87.5"} <= set(lines)
    assert "B,grounding,invalid_coord,0," in lines


def _capped(room: int):
    """Cap this process's data segment at its size now plus `room` bytes (restored after)."""
    soft, hard = resource.getrlimit(resource.RLIMIT_DATA)
    resource.setrlimit(resource.RLIMIT_DATA, (_limits.data_segment() + room, hard))
    return soft, hard


def test_a_frame_without_room_under_the_cap_is_refused_before_polars(monkeypatch):
    table = pa.table({"s": pa.array([f"e{i}" for i in range(1000)]), "n": pa.array(range(1000))})
    need = _sql.polars_room(table, 1)
    # 1000 strings of 2 to 4 bytes, their offsets, 1000 int64, a view per string, the slack
    assert need == table.nbytes + 16 * 1000 + _sql.POLARS_SLACK
    assert _sql.polars_room(table, 6) == 6 * (need - _sql.POLARS_SLACK) + _sql.POLARS_SLACK
    limits = SqlLimits.make(memory="64MB")
    monkeypatch.setattr(_sql, "memory_room", lambda: need - 1)
    with pytest.raises(va.QueryLimitError, match="^OUT: a query needed more memory") as info:
        _sql.polars_frame(table, limits, "OUT: a query")
    assert info.value.limit == "memory"
    monkeypatch.setattr(_sql, "memory_room", lambda: need)
    assert _sql.polars_frame(table, limits).equals(pl.from_arrow(table))


def test_memory_room_is_what_is_left_under_the_cap():
    assert _limits.memory_room() is None  # not capped
    soft, hard = _capped(512 << 20)
    try:
        room = _limits.memory_room()
    finally:
        resource.setrlimit(resource.RLIMIT_DATA, (soft, hard))
    assert room is not None and abs(room - (512 << 20)) < 16 << 20  # a thread may grow it


def test_nested_strings_are_counted_as_views():
    table = pa.table(
        {
            "l": pa.array([["a", "b"], ["c"]]),
            "st": pa.array([{"x": "a", "y": 1}, {"x": "b", "y": 2}]),
            "d": pa.array(["a", "a"]).dictionary_encode(),
            "b": pa.array([b"x", b"y"], pa.large_binary()),
            "n": pa.array([1, 2]),
        }
    )
    assert [_sql._views(c) for c in table.columns] == [3, 2, 1, 2, 0]


@pytest.mark.parametrize(
    "query",
    [
        "SELECT 1 AS a, 2 AS a, 3 AS A",
        "SELECT 'e' || range AS s, range % 7 AS n FROM range(300000)",  # three chunks
        "SELECT * FROM range(0) t(x)",
        "SELECT [1, 2] AS l, {'a': 'x'} AS st, DATE '2024-01-02' AS d, 1.5::DECIMAL(9, 2) AS m",
    ],
)
def test_run_query_gives_what_duckdb_gives_polars(pair_out: Path, query: str):
    """The frame, its names, types and chunks, are those DuckDB's `.pl()` makes."""
    ours = run_query(open_store(pair_out), query, [])
    theirs = duckdb.connect().sql(query).pl()
    assert ours.schema == theirs.schema and ours.equals(theirs)
    assert [s.n_chunks() for s in ours.iter_columns()] == [
        s.n_chunks() for s in theirs.iter_columns()
    ]


def test_vge_sqls_rows_need_room_for_their_text(pair_out: Path, monkeypatch):
    """`vge sql`'s first rows (and each streamed batch) are made a frame only when there is
    room for six copies of them (`WRITE_COPIES`: the frame and its text as written) and for
    what the CSV writer takes for its longest row (`ROW_TEXT_COPIES`)."""
    query = "SELECT repeat('x', 1000000) AS s FROM range(4)"  # 4 MB of text, 4 views
    limits = SqlLimits.make(memory="64MB")
    asked = []
    real = _sql.polars_room
    monkeypatch.setattr(_sql, "polars_room", lambda t, c: asked.append((t, c)) or real(t, c))
    monkeypatch.setattr(_sql, "memory_room", lambda: 1 << 40)
    _sql.sql_head(pair_out, query, 10, limits=limits)
    (table, copies), = asked
    assert copies == 6 and 4_000_000 < table.nbytes < 4_001_000
    # and its CSV text: 16 times its longest row (`ROW_TEXT_COPIES`), 1 MB
    need = 6 * (table.nbytes + 4 * 16) + _sql.POLARS_SLACK + 16 * 1_000_000
    monkeypatch.setattr(_sql, "memory_room", lambda: need - 1)
    with pytest.raises(va.QueryLimitError, match="^the query needed more memory") as info:
        _sql.sql_head(pair_out, query, 10, limits=limits)
    assert info.value.limit == "memory"
    monkeypatch.setattr(_sql, "memory_room", lambda: need)
    head = _sql.sql_head(pair_out, query, 10, limits=limits)
    assert head.frame["s"].str.len_bytes().to_list() == [1_000_000] * 4


def test_row_text_counts_the_text_of_strings_binaries_and_lists():
    table = pa.table(
        {
            "n": pa.array([1, 2, 3]),
            "s": pa.array(["ab", None, "é"]),  # é is 2 bytes
            "b": pa.array([b"", b"xyz", b"q"], pa.binary()),
            "l": pa.array([["a", "bcd"], [], None], pa.list_(pa.string())),
            "ll": pa.array(
                [[["12345"]], [["1"], ["2", None]], [[]]], pa.list_(pa.list_(pa.large_string()))
            ),
        }
    )
    # rows: 2 + 0 + 4 + 5 = 11; 0 + 3 + 0 + 2 = 5; 2 + 1 = 3
    assert _sql.row_text(table) == (11, 0)
    assert _sql.row_text(table.slice(1)) == (5, 0)
    assert _sql.row_text(table.slice(0, 0)) == (0, 0)
    assert _sql.row_text(pa.table({"n": [1, 2]})) == (0, 0)


def test_row_text_counts_dictionary_encoded_text_by_value():
    """An ENUM (a dictionary of strings) counts each row's value, as a list of them does,
    and the text its values stand for in all; a dictionary of numbers counts nothing."""
    words = pa.array(["", "long" * 250_000, "abc"])  # 0, 1,000,000 and 3 bytes
    enum = pa.DictionaryArray.from_arrays(pa.array([2, None, 0, 1, 2], pa.int8()), words)
    listed = pa.ListArray.from_arrays(pa.array([0, 2, 2, 3, 3, 5], pa.int32()), enum)
    numbers = pa.DictionaryArray.from_arrays(pa.array([0, 0, 0, 0, 0]), pa.array([10**9]))
    table = pa.table({"e": enum, "l": listed, "n": numbers})
    # e: 3, 0, 0, 1e6, 3; l: [3, 0], [], [0], [], [1e6, 3]; rows: 6, 0, 0, 1e6, 1e6 + 6
    # encoded: e 1e6 + 6, l 1e6 + 6
    assert _sql.row_text(table) == (1_000_006, 2_000_012)
    assert _sql.row_text(table.slice(0, 3)) == (6, 6)
    assert _sql.row_text(table.select(["n"])) == (0, 0)


_LONG = "x" * 100_000
_ENUM = f"SELECT CAST(repeat('x', 100000) AS ENUM('{_LONG}')) AS e FROM range(ROWS)"


@pytest.mark.parametrize(
    ("query", "limit", "disk", "fits", "written"),
    [
        # One 15 MB value: its frame fits the room left under a 128 MB limit, but polars'
        # CSV writer takes about 14 times a row's text. At BASE the process aborted, hung for
        # ever (RUST_BACKTRACE=1) or printed a MemoryError with a panic from polars' threads.
        (
            "SELECT repeat('x', 15000000) AS s",
            "128MB",
            "256 MB",
            "SELECT repeat('x', 2000000) AS s",
            "s\n" + "x" * 2_000_000 + "\n",
        ),
        # One 100 kB ENUM value on 40,000 rows: each batch of 2,048 rows holds the value once
        # (a few hundred kB) and stands for 205 MB of text when written. The room asked for
        # counted only the batch's buffers, and the process aborted inside polars' writer.
        (
            _ENUM.replace("ROWS", "40000"),
            "512MB",
            "1 GB",
            _ENUM.replace("ROWS", "3"),
            "e\n" + (_LONG + "\n") * 3,
        ),
    ],
    ids=["long-row", "enum"],
)
def test_text_too_long_to_write_under_the_cap_ends_in_one_line(
    pair_out: Path, tmp_path: Path, query: str, limit: str, disk: str, fits: str, written: str
):
    stopped = _vge("sql", str(pair_out), query, "-f", "csv", "--memory-limit", limit, cwd=tmp_path)
    assert stopped.returncode == 1, stopped.stderr[-2000:]
    assert stopped.stderr.splitlines() == [
        f"error: the query needed more memory than its limit ({limit[:-2]} MB in memory, "
        f"{disk} on disk) and was stopped (--memory-limit sets the limit)"
    ]
    done = _vge("sql", str(pair_out), fits, "-f", "csv", cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout == written


PANIC = """
import io
import polars as pl
from vge_analytics.store import SqlLimits, process_memory_cap
frame = pl.DataFrame({"s": ["x" * 100_000_000]})
with process_memory_cap(SqlLimits.make(memory="128MB")):
    try:
        frame.write_csv(io.StringIO())
        print("written")
    except BaseException as exc:  # polars' PanicException is a BaseException
        print("raised")
"""


def test_a_panic_in_polars_under_the_cap_raises_instead_of_hanging(tmp_path: Path):
    """With RUST_BACKTRACE=1, a panic in polars' threads under the cap (the CSV writer's
    Python string could not be made) loaded the library's symbols to print a backtrace,
    failed to allocate, and waited for ever on the printer's own lock; the cap now runs
    without RUST_BACKTRACE (and puts it back after), and the process ends at once. It
    raises, or, when another of polars' threads fails to allocate while the panic unwinds
    (polars 2.x, now and then, as `process_memory_cap` says of any allocation polars cannot
    make), polars aborts it: never a hang."""
    done = subprocess.run(
        [sys.executable, "-c", PANIC],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=tmp_path,
        env={**os.environ, "RUST_BACKTRACE": "1", "PYTHONPATH": str(Path(va.__file__).parents[1])},
    )
    aborted = done.returncode == -signal.SIGABRT and "memory allocation of" in done.stderr
    assert done.stdout == "raised\n" or aborted, done.stderr[-2000:]


def test_the_cap_puts_rust_backtrace_back(monkeypatch):
    monkeypatch.setenv("RUST_BACKTRACE", "full")
    with _limits.process_memory_cap(SqlLimits.make(memory="1GB")):
        assert "RUST_BACKTRACE" not in os.environ
    assert os.environ["RUST_BACKTRACE"] == "full"
