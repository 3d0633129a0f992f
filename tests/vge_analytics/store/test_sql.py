"""`sql`: read-only queries; writing statements and files outside OUT are refused."""

from __future__ import annotations

from pathlib import Path

import pytest

import vge_analytics as va

WRITES = [
    "INSERT INTO steps SELECT * FROM steps",
    "CREATE TABLE t AS SELECT 1",
    "CREATE OR REPLACE VIEW steps AS SELECT 1 AS x",
    "DROP VIEW episodes",
    "DELETE FROM goals",
    "UPDATE runs SET model = 'x'",
    "COPY (SELECT 1) TO '/tmp/vge_sql_copy.csv'",
    "ATTACH '/tmp/vge_sql_attach.db' AS other",
    "PRAGMA enable_profiling",
    "SET enable_external_access = true",
    "RESET lock_configuration",
    "INSTALL httpfs",
    "LOAD httpfs",
    "CALL pragma_version()",
    "EXPORT DATABASE '/tmp/vge_sql_export'",
    "EXPLAIN ANALYZE CREATE TABLE t AS SELECT 1",
    "SELECT 1; DROP VIEW steps",
]

FILES = [
    "SELECT * FROM read_csv('/etc/passwd')",
    "SELECT * FROM read_text('/etc/hostname')",
    "SELECT * FROM read_parquet('/tmp/*.parquet')",
    "SELECT * FROM glob('/*')",
    "SELECT * FROM read_json('/etc/os-release')",
]


@pytest.mark.parametrize("query", WRITES)
def test_writing_statements_are_refused(hand_out: Path, query: str) -> None:
    with pytest.raises(va.QueryRefused) as info:
        va.sql(hand_out, query)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("query", FILES)
def test_files_outside_out_are_refused(hand_out: Path, query: str) -> None:
    with pytest.raises(va.QueryRefused, match="outside"):
        va.sql(hand_out, query)


def test_views_survive_refusals(hand_out: Path) -> None:
    for query in WRITES:
        with pytest.raises(va.QueryRefused):
            va.sql(hand_out, query)
    assert not Path("/tmp/vge_sql_copy.csv").exists()
    df = va.sql(hand_out, "SELECT count(*) AS n FROM steps")
    assert df["n"][0] == 77
    # and the metrics (same cached connection) still work
    assert va.metrics(hand_out, metrics="SR")["SR"].to_list()[0] == pytest.approx(100 * 4 / 7)


def test_read_only_queries_work(hand_out: Path) -> None:
    df = va.sql(
        hand_out,
        "WITH t AS (SELECT run_id, count(*) AS n FROM episodes GROUP BY run_id) "
        "SELECT * FROM t ORDER BY run_id",
    )
    assert df.rows() == [("kettle-vlm", 7), ("oven-human", 5)]
    assert va.sql(hand_out, "DESCRIBE goals").height > 10
    assert va.sql(hand_out, "EXPLAIN SELECT * FROM runs").height >= 1
    # The tables are the way in: DuckDB opens no file, OUT's own included (PROTOCOL §9.1).
    own = hand_out / "runs" / "runs.parquet"
    with pytest.raises(va.QueryRefused, match="no file is opened, in OUT or elsewhere"):
        va.sql(hand_out, f"SELECT count(*) AS n FROM read_parquet('{own}')")


def test_bad_queries(hand_out: Path) -> None:
    with pytest.raises(va.QueryError, match="cannot parse"):
        va.sql(hand_out, "SELEC 1")
    with pytest.raises(va.QueryError):
        va.sql(hand_out, "SELECT no_such_column FROM steps")
    with pytest.raises(va.QueryRefused, match="empty"):
        va.sql(hand_out, "   ")
