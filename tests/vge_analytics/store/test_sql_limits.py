"""SQL within limits: runaway queries end with one line, and memory stays bounded.

The command-line tests run `vge sql` on the bundled sample (24,709 steps: the cross join of
the issue is 610 million rows) as a real process under an address-space bound of its own
(`tests.bounded`), with small limits (2 s, 256 MB) so each takes seconds. Memory is judged
against the same command running `SELECT 1`: the query may add at most what
`memory_headroom` allows (the process cap `vge sql` takes), however much it asks for.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

import vge_analytics as va
from replay import ConfigError
from tests.bounded import run_bounded
from vge_analytics.store._limits import SqlLimits, memory_headroom, parse_size, process_memory_cap
from vge_analytics.store._sql import sql_head, stream, unique_names

TIMEOUT = 2.0
MEMORY = "256MB"
LIMITS = SqlLimits.make(memory=MEMORY, timeout=TIMEOUT)

CROSS_JOIN = "select a.output, b.output from steps a, steps b"
NEVER_ENDS = (
    "with recursive r(n) as (select 1 union all select n + 1 from r) select count(*) from r"
)
GROWS = "with recursive r(s) as (select 'x' union all select s || s from r) select count(*) from r"
HUGE_VALUE = "select repeat('x', 1500000000) as s"

TIME_ERROR = f"error: the query ran past its time limit of {TIMEOUT:g} s and was stopped"
MEMORY_ERROR = (
    "error: the query needed more memory than its limit (256 MB in memory, 512 MB on disk) "
    "and was stopped (--memory-limit sets the limit)"
)


def vge_sql(out: Path, query: str, *options: str):
    cmd = [sys.executable, "-m", "vge_analytics.cli", "sql", str(out), query]
    return run_bounded([*cmd, "--timeout", f"{TIMEOUT:g}", "--memory-limit", MEMORY, *options])


@pytest.fixture(scope="module")
def baseline(sample_out):
    """`vge sql OUT "SELECT 1"`: the process's own size and start-up time."""
    done = vge_sql(sample_out, "select 1 as one", "--format", "csv")
    assert done.returncode == 0 and done.stdout_head == b"one\n1\n", done.stderr
    return done


def assert_bounded(done, baseline) -> None:
    assert done.peak_memory <= baseline.peak_memory + memory_headroom(LIMITS), (
        done.peak_memory,
        baseline.peak_memory,
    )
    # Ended by its limit (the message names which): start-up, the limit and a second for the
    # last batch on an idle machine; ten times that on a busy one, never the minutes of a
    # query that nothing stops.
    assert done.seconds <= 10 * (baseline.seconds + TIMEOUT + 1.5), done.seconds


def test_cross_join_streams_csv_until_the_time_limit(sample_out, baseline):
    done = vge_sql(sample_out, CROSS_JOIN, "--format", "csv")
    assert done.returncode == 1
    assert done.stderr.strip() == f"{TIME_ERROR} (--timeout sets the limit)"
    # Rows were written as they came: hundreds of megabytes in two seconds, memory flat.
    assert done.stdout_head.startswith(b"output,output_1\n")
    assert done.stdout_bytes > 10 * 1024**2
    assert done.peak_memory <= baseline.peak_memory + 128 * 1024**2, done.peak_memory
    assert_bounded(done, baseline)


def test_cross_join_in_a_table_shows_the_first_rows(sample_out, baseline):
    done = vge_sql(sample_out, CROSS_JOIN, "--format", "markdown", "--max-rows", "50")
    assert done.returncode == 0, done.stderr
    assert done.stderr.strip() == (
        "note: the first 50 rows are shown; --format csv or json writes every row"
    )
    assert done.stdout_head.startswith(b"| output | output_1 |")
    assert_bounded(done, baseline)


def test_recursive_query_that_never_ends_stops_at_the_time_limit(sample_out, baseline):
    done = vge_sql(sample_out, NEVER_ENDS, "--format", "json")
    assert done.returncode == 1
    assert done.stderr.strip() == f"{TIME_ERROR} (--timeout sets the limit)"
    assert done.stdout_bytes == 0
    assert_bounded(done, baseline)


@pytest.mark.parametrize("query", [GROWS, HUGE_VALUE], ids=["growing", "huge-value"])
def test_queries_past_the_memory_limit_stop(sample_out, baseline, query):
    # GROWS doubles a string until it is past the limits; HUGE_VALUE is one 1.5 GB string,
    # which DuckDB does not account for: the process cap stops it.
    done = vge_sql(sample_out, query, "--format", "csv")
    assert done.returncode == 1
    assert done.stderr.strip() == MEMORY_ERROR
    assert_bounded(done, baseline)


# ------------------------------------------------------------------- Python API


def test_python_api_limits(hand_out):
    with pytest.raises(va.QueryLimitError, match="time limit of 0.5 s") as info:
        va.sql(hand_out, NEVER_ENDS, timeout=0.5)
    assert info.value.limit == "time" and "\n" not in str(info.value)
    with pytest.raises(va.QueryLimitError, match="more memory than its limit") as info:
        va.sql(hand_out, GROWS, memory_limit="64MB", timeout=30)
    assert info.value.limit == "memory"
    # DuckDB's part fits in 64 MB (it streams); the collected result does not.
    with pytest.raises(va.QueryLimitError, match=r"the result is larger .* \(64 MB\)") as info:
        va.sql(hand_out, "select range from range(20000000)", memory_limit="64MB")
    assert info.value.limit == "result"
    # The same connection answers the next query.
    assert va.sql(hand_out, "select count(*) as n from steps", timeout=30)["n"][0] == 77


def test_head_reads_only_what_it_shows(sample_out):
    head = sql_head(sample_out, CROSS_JOIN, 5, limits=LIMITS)
    assert head.truncated and head.frame.columns == ["output", "output_1"]
    assert head.frame.height == 5
    exact = sql_head(sample_out, "select * from range(7)", 7, limits=LIMITS)
    assert exact.frame["range"].to_list() == list(range(7)) and not exact.truncated
    empty = sql_head(sample_out, "select run_id, step from steps where false", 5, limits=LIMITS)
    assert empty.frame.columns == ["run_id", "step"] and empty.frame.height == 0


def test_streamed_csv_and_json_equal_the_whole_rendering(hand_out, capsys):
    from vge_analytics.commands._output import emit_stream
    from vge_analytics.reports._format import render

    query = (
        "select run_id, episode_id, step, params, x, success "
        "from steps join episodes using (run_id, episode_id) order by all"
    )
    whole = va.sql(hand_out, query)
    for fmt in ("csv", "json"):
        with stream(hand_out, query, limits=LIMITS, batch_rows=10) as result:
            emit_stream(result, fmt)
        expected = render(whole, fmt)
        assert capsys.readouterr().out == expected + ("" if expected.endswith("\n") else "\n")
    with stream(hand_out, "select 1 as a where false", limits=LIMITS) as result:
        emit_stream(result, "json")
    assert capsys.readouterr().out == "[]\n"


def test_duplicate_column_names_are_made_unique():
    assert unique_names(["a", "a", "a_1", "A", "b"]) == ["a", "a_1", "a_1_1", "A_2", "b"]


def test_sizes_and_the_process_cap():
    assert parse_size("256MB") == parse_size("256 MiB") == 256 * 1024**2
    assert parse_size("1.5G") == 3 * 512 * 1024**2
    with pytest.raises(ConfigError, match="not a memory size"):
        parse_size("lots")
    with pytest.raises(ConfigError, match="below 16 MB"):
        parse_size("1MB")
    import resource

    before = resource.getrlimit(resource.RLIMIT_DATA)
    with process_memory_cap(SqlLimits.make(memory="64MB")), pytest.raises(MemoryError):
        bytearray(2 * 1024**3)
    assert resource.getrlimit(resource.RLIMIT_DATA) == before
