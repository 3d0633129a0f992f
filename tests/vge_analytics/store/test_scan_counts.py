"""The first step count by polars runs in a process of its own, capped as the store's queries
are (`store._scan_counts`): steps whose counted columns would take polars past that cap are
counted by DuckDB's query instead, the same rows, and this process's memory stays bounded."""

from __future__ import annotations

import os
import resource
import subprocess
import sys
from pathlib import Path

import polars as pl
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

import vge_analytics as va
from tests.vge_analytics.store.conftest import POLARS_FROM_BYTES
from tests.vge_analytics.store.kept import copy_out
from vge_analytics.store import _isolated, _scan_counts, _step_counts, open_store, run_query


def _with_steps(pair_out: Path, target: Path, steps: pa.Table) -> Path:
    """A copy of `pair_out` whose run B's steps are `steps` (its only file)."""
    out = copy_out(pair_out, target)
    (part,) = sorted((out / "steps" / "run_id=B").glob("*.parquet"))
    pq.write_table(steps, part, store_schema=False)  # its strings read as strings
    va.clear_cache()
    return out


def _steps(rows: int, error_type: pl.Expr) -> pa.Table:
    """`rows` scored steps of run B (Lamp, interactions on views `v<row>`) of `error_type`."""
    return (
        pl.select(n=pl.int_range(rows))
        .select(
            category=pl.lit("Lamp"),
            error_type=error_type,
            device_id=pl.lit("Lamp_001"),
            view_before=pl.format("v{}", "n"),
            switch_class=pl.lit("none"),
            truncated=pl.lit(False),
            is_interaction=pl.lit(True),
            is_switch=pl.lit(False),
        )
        .to_arrow()
    )


def _counted(out: Path, name: str, memory: str, monkeypatch) -> tuple[pl.DataFrame, int]:
    """The kept counts `name` of OUT made within `memory`, and how many times DuckDB's
    query counted them."""
    calls = []
    real = _step_counts.run_query
    monkeypatch.setattr(
        _step_counts, "run_query", lambda *a, **k: calls.append(1) or real(*a, **k)
    )
    with va.query_limits(memory=memory):
        kept = _step_counts._counts(open_store(out), name)
    assert kept is not None
    return kept, len(calls)


def _by_duckdb(out: Path, name: str) -> pl.DataFrame:
    store = open_store(out)
    return run_query(store, *_step_counts._query(store, _step_counts.PARTS[name]))


def _peak() -> int:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


@pytest.mark.parametrize("name", sorted(_step_counts.PARTS))
def test_the_sample_is_counted_by_polars_in_its_process(
    sample_out: Path, tmp_path: Path, monkeypatch, name: str
):
    out = copy_out(sample_out, tmp_path / "out")
    kept, by_duckdb = _counted(out, name, "256MB", monkeypatch)
    ran = _scan_counts.last_process
    assert by_duckdb == 0 and ran is not None and ran.counted and ran.peak_memory > 0
    assert kept.equals(_by_duckdb(out, name))


def test_a_million_error_types_are_counted_by_duckdb_the_same_rows(
    pair_out: Path, tmp_path: Path, monkeypatch
):
    # 1,000,000 error types in run B, a group each: polars' count of them takes 0.3 GB
    # resident and 3.5 GB of data segment (its sort reserves it); its process may add 256 +
    # 256 MB (`memory_headroom`) and is stopped there. DuckDB's count fits in 256 MB, its
    # frame too (at 128 MB DuckDB's result leaves too little room under the cap for the
    # frame: the one-line error, test_result_room)
    rows = 1_000_000
    out = _with_steps(pair_out, tmp_path / "out", _steps(rows, pl.format("e{}", "n")))
    before = _peak()
    kept, by_duckdb = _counted(out, "errors", "256MB", monkeypatch)
    assert by_duckdb == 1 and _scan_counts.last_process == (False, 0.0, 0, 0)
    assert _peak() - before < 512 << 20  # DuckDB's 256 MB, its million rows, the kept file
    b = kept.filter(pl.col("run_id") == "B")
    assert (b.height, b["scored"].min(), b["scored"].max()) == (rows, 1, 1)
    assert b["error_type"].head(3).to_list() == ["e0", "e1", "e10"]  # sorted as text
    a = _by_duckdb(pair_out, "errors")
    assert kept.filter(pl.col("run_id") == "A").equals(a.filter(pl.col("run_id") == "A"))


def test_a_huge_error_type_is_counted_by_duckdb_the_same_rows(
    pair_out: Path, tmp_path: Path, monkeypatch
):
    # one error type of 100 KB on 40,000 steps: a file of a few hundred KB (a dictionary of
    # one value), one group, but polars' count copies the key per step: 0.95 GB resident
    rows, size = 40_000, 100_000
    huge = pl.lit("x" * size).cast(pl.Categorical)  # written as a dictionary: one value
    out = _with_steps(pair_out, tmp_path / "out", _steps(rows, huge))
    assert sum(f.stat().st_size for f in (out / "steps" / "run_id=B").iterdir()) < 1 << 20
    before = _peak()
    kept, by_duckdb = _counted(out, "errors", "64MB", monkeypatch)  # may add 320 MB
    assert by_duckdb == 1 and _scan_counts.last_process == (False, 0.0, 0, 0)
    assert _peak() - before < 256 << 20  # polars' 0.95 GB were not this process's
    b = kept.filter(pl.col("run_id") == "B")
    assert b.rows() == [("B", "Lamp", "x" * size, rows)]
    assert kept.equals(_by_duckdb(out, "errors"))


def test_chunks_are_counted_until_the_time_limit_between_them(pair_out: Path, monkeypatch):
    store = open_store(pair_out)
    part = _step_counts.PARTS["errors"]
    chunks = _scan_counts._chunks(_scan_counts._runs(store))
    assert [sorted(held) for held, _ in chunks] == [["A", "B"]]
    one_each = [  # a chunk a run
        ({run}, [p for p in paths if f"run_id={run}" in p])
        for held, paths in chunks
        for run in sorted(held)
    ]
    schema = _scan_counts._schema(store, part.keys, ["truncated"])
    counter = _scan_counts._counter(schema, list(part.keys), part.name, None, None)
    counted = []
    clock = iter([10.0, 20.0])  # looked at before the second chunk only: 10 s, then 20 s
    monkeypatch.setattr(_scan_counts, "monotonic", lambda: next(clock))

    def stop():
        return va.QueryLimitError("stopped", limit="time")

    parts = []
    count = lambda p: counted.append(p) or counter(p)  # noqa: E731
    assert _scan_counts._count(one_each, count, 15.0, stop, parts.append)
    assert len(counted) == 2 and len(parts) == 2  # at 10 s: before its end
    with pytest.raises(va.QueryLimitError, match="stopped"):
        _scan_counts._count(one_each, count, 15.0, stop, parts.append)
    assert len(counted) == 3  # the first counted, the second not begun (at 20 s)
    whole = pl.concat(parts[:2])
    assert whole.equals(_by_duckdb(pair_out, "errors"))


def test_with_every_query_process_taken_duckdb_counts_at_once(pair_out: Path):
    part = _step_counts.PARTS["views"]
    args = (part.keys, part.name, part.where, part.only)
    slots = _isolated._slots(1)
    with va.query_limits(isolated=True, max_queries=1):  # a server's bounds, one process
        store = open_store(pair_out)
        assert slots.acquire(blocking=False)  # the SQL page's query, say
        try:
            assert _scan_counts.count_steps(store, *args) is None  # not waited for
        finally:
            slots.release()
        counted = _scan_counts.count_steps(store, *args)
    assert counted is not None and counted.equals(_by_duckdb(pair_out, "views"))


def test_counts_past_what_this_process_may_hold_of_them_are_duckdbs(
    pair_out: Path, monkeypatch
):
    store = open_store(pair_out)
    part = _step_counts.PARTS["views"]
    args = (part.keys, part.name, part.where, part.only)
    assert _scan_counts.count_steps(store, *args) is not None
    monkeypatch.setattr(_scan_counts, "memory_headroom", lambda limits: 100)  # bytes here
    assert _scan_counts.count_steps(store, *args) is None
    assert _scan_counts.last_process == (False, 0.0, 0, 0)  # ended, not answered


def test_a_count_silent_past_the_time_limit_is_ended(pair_out: Path, monkeypatch):
    part = _step_counts.PARTS["views"]
    clock = iter([0.0])  # the count's end set at 0 + 150 s, then looked at 10^6 s later
    monkeypatch.setattr(_scan_counts, "monotonic", lambda: next(clock, 1e6))
    monkeypatch.setattr(_scan_counts, "GRACE", 0.0)  # not waited for past its end
    with va.query_limits(timeout=150):
        store = open_store(pair_out)
        with pytest.raises(va.QueryLimitError, match="time limit of 150 s") as info:
            _scan_counts.count_steps(store, part.keys, part.name, part.where, part.only)
    assert info.value.limit == "time" and _scan_counts.last_process == (False, 0.0, 0, 0)


@pytest.mark.parametrize(
    ("memory", "room"),
    [
        ("64MB", (64 + 256) << 20),  # the limit and half again, at least 256 MB more
        ("1GB", (1024 + 512) << 20),  # the limit and half again
    ],
)
def test_the_count_may_add_the_memory_limit_and_half_again(
    pair_out: Path, memory: str, room: int
):
    part = _step_counts.PARTS["errors"]
    with va.query_limits(memory=memory):
        store = open_store(pair_out)
        counted = _scan_counts.count_steps(store, part.keys, part.name, part.where, part.only)
    assert counted is not None
    ran = _scan_counts.last_process
    assert ran is not None and ran.counted
    assert abs(ran.room - room) < 16 << 20  # (its data segment read twice: a thread may grow it)


def test_steps_under_the_threshold_are_counted_by_duckdb(
    sample_out: Path, tmp_path: Path, monkeypatch
):
    """The sample's steps files (1.8 MB) are under the module's `POLARS_FROM_BYTES`:
    DuckDB's query counts them, no count process is started, and the rows are polars' to
    the unit."""
    out = copy_out(sample_out, tmp_path / "out")
    by_polars, _ = _counted(out, "errors", "256MB", monkeypatch)
    size = sum(p.stat().st_size for p in (out / "steps").rglob("*.parquet"))
    assert 0 < size < POLARS_FROM_BYTES
    monkeypatch.setattr(_scan_counts, "POLARS_FROM_BYTES", POLARS_FROM_BYTES)
    _scan_counts.last_process = None
    for kept in (out / ".metric-cache").glob("counts_*"):
        kept.unlink()
    by_duckdb, calls = _counted(out, "errors", "256MB", monkeypatch)
    assert calls == 1 and _scan_counts.last_process is None
    assert by_duckdb.equals(by_polars)
    monkeypatch.setattr(_scan_counts, "POLARS_FROM_BYTES", size)  # at the threshold: polars
    for kept in (out / ".metric-cache").glob("counts_*"):
        kept.unlink()
    again, calls = _counted(out, "errors", "256MB", monkeypatch)
    assert calls == 0 and _scan_counts.last_process is not None and again.equals(by_polars)


def test_a_script_without_a_main_guard_counts_once(sample_out: Path, tmp_path: Path):
    """A user's script that counts at its top level, with no `if __name__ == "__main__":`,
    runs once: the count's process is not told to run the parent's script first (as
    multiprocessing would, where it would start another count and fail)."""
    out = copy_out(sample_out, tmp_path / "out")
    script = tmp_path / "count.py"
    script.write_text(
        "import vge_analytics as va\n"
        "from vge_analytics.store import _scan_counts\n"
        "_scan_counts.POLARS_FROM_BYTES = 0\n"
        "print('script ran', flush=True)\n"
        "with va.query_limits(memory='256MB'):\n"
        f"    shares = va.error_distribution({str(out)!r})\n"
        "print('counted', _scan_counts.last_process.counted, len(shares) > 0)\n"
    )
    done = subprocess.run(
        [sys.executable, str(script)],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=tmp_path,
        env={**os.environ, "PYTHONPATH": str(Path(va.__file__).parents[1])},
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == ["script ran", "counted True True"]
    assert "Traceback" not in done.stderr
