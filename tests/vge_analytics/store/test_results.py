"""Results kept beside OUT (`store._results`, docs/METRICS.md): the dashboard's values read back
bit for bit, a file that is really read, another file when OUT, the arguments or the
definitions change, and the bounds (size, count, links, an OUT that cannot be written)."""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import polars as pl
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

import vge_analytics as va
from replay.io import METRIC_CACHE_DIR
from tests.vge_analytics.store.kept import copy_out
from vge_analytics import dashboard as dash
from vge_analytics.store import _results

_copy = copy_out  # an OUT without its cache folder


def _results_kept(out: Path) -> list[str]:
    folder = out / METRIC_CACHE_DIR
    return sorted(p.name for p in folder.glob("result-*.arrow")) if folder.is_dir() else []


def _same(a, b) -> None:
    """Equal values of the same kinds, every float the same bits (frames: same schema, same
    rows, float columns the same bytes)."""
    assert type(a) is type(b)
    if isinstance(a, pl.DataFrame):
        assert a.schema == b.schema
        assert a.equals(b, null_equal=True)
        for name, dtype in a.schema.items():
            if dtype.is_float():
                assert a[name].to_numpy().tobytes() == b[name].to_numpy().tobytes(), name
    elif isinstance(a, (tuple, list)):
        assert len(a) == len(b)
        for x, y in zip(a, b, strict=True):
            _same(x, y)
    elif isinstance(a, dict):
        assert list(a) == list(b)
        for k in a:
            _same(a[k], b[k])
    elif isinstance(a, float):
        assert a.hex() == b.hex()
    elif dataclasses.is_dataclass(a):
        for f in dataclasses.fields(a):
            _same(getattr(a, f.name), getattr(b, f.name))
    else:
        assert a == b


def _kept(out: Path, name: str, fn, *args, version: str = "", **kwargs):
    return _results.kept_result(
        out, name, (args, kwargs), lambda: fn(out, *args, **kwargs), version=version
    )


def _pages_calls(out: Path) -> list[tuple]:
    """What the slow pages ask for at 100x, as they ask for it (app/_data.py)."""
    by = ["run_id", "model"]
    views = dash.interaction_views(out, where={})
    device, view = views["device_id"][0], views["view"][0]  # the most clicked
    runs = va.runs(out)["run_id"].to_list()
    return [
        ("runs", va.runs, (), {}),
        ("categories", dash.column_values, ("episodes", "category"), {}),
        ("goal counts", dash.column_values, ("episodes", "n_goals"), {}),
        ("facets", dash.run_facets, (), {}),
        ("metrics", va.metrics, (), {"by": by, "where": {}, "metrics_dir": None}),
        ("costs", dash.cost_table, (by, {}), {}),
        (
            "intervals",
            va.metric_intervals,
            (),
            {"metric": "SR", "by": by, "where": {}, "resamples": 200},
        ),
        (
            "distance intervals",
            va.metric_intervals,
            (),
            {"metric": "AvgDist", "by": ["model"], "where": {}, "resamples": 200},
        ),
        ("errors", va.error_distribution, (), {"by": by, "where": {}, "labels": True}),
        ("error sample", dash.error_step_sample, ("invalid_coord",), {"where": {}}),
        ("switches", va.switch_classes, (), {"by": by, "where": {}}),
        ("views", dash.interaction_views, (), {"where": {}}),
        ("clicks", dash.click_points, (device, view), {"where": {}}),
        ("pair", dash.pair_rows, (runs[0], runs[1]), {}),
        ("columns", dash.table_columns_frame, (), {}),
        ("compare", va.compare, (runs[0], runs[1]), {"resamples": 200}),
        ("completeness", va.completeness, (), {}),
        ("summary", dash.out_summary, (), {}),
    ]


def test_kept_values_are_the_computed_values_on_the_sample(sample_out: Path, tmp_path: Path):
    out = _copy(sample_out, tmp_path / "out")
    calls = _pages_calls(out)
    for name, fn, args, kwargs in calls:
        direct = fn(out, *args, **kwargs)
        first = _kept(out, name, fn, *args, **kwargs)  # computes and keeps
        va.clear_cache()
        again = _results.kept_result(  # read back: never computed
            out, name, (args, kwargs), lambda name=name: pytest.fail(f"{name} computed again")
        )
        _same(first, direct)
        _same(again, direct)
    assert len(_results_kept(out)) == len(calls)


def test_the_kept_file_is_what_answers(pair_out: Path, tmp_path: Path):
    out = _copy(pair_out, tmp_path / "out")
    want = _kept(out, "runs", va.runs)
    (name,) = _results_kept(out)
    # Another value written under the same name: the next call shows it.
    _results._write(out / METRIC_CACHE_DIR / name, (want.head(1), 7, [1.5, None, "x"]))
    got = _kept(out, "runs", va.runs)
    _same(got, (want.head(1), 7, [1.5, None, "x"]))


def test_other_arguments_or_definitions_name_another_file(pair_out: Path, tmp_path: Path):
    out = _copy(pair_out, tmp_path / "out")
    a = _kept(out, "metrics", va.metrics, by=["run_id"], metrics=["SR"])
    b = _kept(out, "metrics", va.metrics, by=["model"], metrics=["SR"])
    c = _kept(out, "metrics", va.metrics, by=["run_id"], metrics=["SR"], version="other")
    assert len(_results_kept(out)) == 3
    _same(a, va.metrics(out, by=["run_id"], metrics=["SR"]))
    _same(b, va.metrics(out, by=["model"], metrics=["SR"]))
    _same(c, a)
    # A tuple and a list of the same items are other arguments.
    assert _results._key("f", ((1,),), "") != _results._key("f", ([1],), "")


def test_a_changed_out_names_another_file(pair_out: Path, tmp_path: Path):
    """A table file rewritten (here by hand; a replay rewrites the manifest too) changes OUT's
    contents key: the result is computed again, from the new tables, and the results kept for
    the old contents are removed."""
    out = _copy(pair_out, tmp_path / "out")
    before = _kept(out, "metrics", va.metrics, by=["run_id"], metrics=["SR"])
    assert before["SR"].to_list() == pytest.approx([20.0, 700 / 11])
    old = _results_kept(out)
    (part,) = sorted((out / "episodes" / "run_id=A").glob("*.parquet"))
    table = pq.read_table(part)
    column = table.schema.get_field_index("success")
    pq.write_table(table.set_column(column, "success", pa.array([True] * table.num_rows)), part)
    va.clear_cache()
    after = _kept(out, "metrics", va.metrics, by=["run_id"], metrics=["SR"])
    assert after["SR"].to_list() == pytest.approx([100.0, 700 / 11])
    new = _results_kept(out)
    assert len(new) == 1 and new != old


def test_another_code_names_another_file(pair_out: Path, tmp_path: Path, monkeypatch):
    out = _copy(pair_out, tmp_path / "out")
    _kept(out, "runs", va.runs)
    monkeypatch.setattr(_results, "code_key", lambda: "another-version")
    _kept(out, "runs", va.runs)
    assert len(_results_kept(out)) == 2


def test_values_of_other_kinds_are_computed_every_time(pair_out: Path, tmp_path: Path):
    out = _copy(pair_out, tmp_path / "out")
    calls = []

    def paths():
        calls.append(1)
        return [out]  # a path: not kept

    first = _results.kept_result(out, "paths", (), paths)
    again = _results.kept_result(out, "paths", (), paths)
    assert first == again == [out] and len(calls) == 2
    assert _results_kept(out) == []
    # An argument of another kind: nothing kept either.
    assert _results.kept_result(out, "f", (object(),), lambda: 3) == 3
    assert _results_kept(out) == []


def test_a_record_names_a_class_of_this_code_only(pair_out: Path, tmp_path: Path):
    """A record is made again from a dataclass of `replay` or `vge_analytics` already loaded;
    a file naming any other class is not read (it is computed and written again)."""
    out = _copy(pair_out, tmp_path / "out")
    want = _results.kept_result(out, "done", (), lambda: va.completeness(out))
    (name,) = _results_kept(out)
    path = out / METRIC_CACHE_DIR / name
    data = path.read_bytes()
    table = pa.ipc.open_file(pa.py_buffer(data)).read_all()
    shape = table.schema.metadata[b"vge-result"].decode()
    record = want[0].__class__
    for other in ("subprocess:Popen", "os:system", f"{record.__module__}:open_store"):
        forged = shape.replace(f"{record.__module__}:{record.__qualname__}", other)
        forged_table = table.replace_schema_metadata({b"vge-result": forged.encode()})
        sink = pa.BufferOutputStream()
        with pa.ipc.new_file(sink, forged_table.schema) as writer:
            writer.write_table(forged_table)
        path.write_bytes(sink.getvalue().to_pybytes())
        assert _results._read(path) == (False, None), other
    assert _results.kept_result(out, "done", (), lambda: va.completeness(out)) == want


def test_the_bounds(pair_out: Path, tmp_path: Path, monkeypatch):
    out = _copy(pair_out, tmp_path / "out")
    monkeypatch.setattr(_results, "MAX_RESULTS", 2)
    for k in range(4):
        assert _results.kept_result(out, "n", (k,), lambda k=k: k * 10) == k * 10
    assert len(_results_kept(out)) == 2  # the two newest
    monkeypatch.setattr(_results, "MAX_RESULT_BYTES", 1000)
    frame = pl.DataFrame({"x": list(range(1000))})
    assert _results.kept_result(out, "big", (), lambda: frame).equals(frame)
    assert len(_results_kept(out)) == 2  # too large to keep


def test_a_result_file_that_is_a_link_is_not_read(pair_out: Path, tmp_path: Path):
    out = _copy(pair_out, tmp_path / "out")
    _results.kept_result(out, "n", (), lambda: 1)
    (name,) = _results_kept(out)
    elsewhere = tmp_path / "elsewhere.arrow"
    _results._write(elsewhere, 2)
    path = out / METRIC_CACHE_DIR / name
    path.unlink()
    path.symlink_to(elsewhere)
    assert _results.kept_result(out, "n", (), lambda: 1) == 1
    assert not path.is_symlink() and elsewhere.is_file()  # replaced beside, never written through


def test_a_cache_folder_that_is_a_link_is_left_alone(pair_out: Path, tmp_path: Path):
    out = _copy(pair_out, tmp_path / "out")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (out / METRIC_CACHE_DIR).symlink_to(elsewhere)
    assert _results.kept_result(out, "n", (), lambda: 1) == 1
    assert list(elsewhere.iterdir()) == []


def test_an_out_that_cannot_be_written_computes(pair_out: Path, tmp_path: Path, monkeypatch):
    out = _copy(pair_out, tmp_path / "out")

    def refuse(*args, **kwargs):
        raise PermissionError(13, "Read-only file system")

    monkeypatch.setattr(_results, "atomic_file", refuse)
    assert _results.kept_result(out, "n", (), lambda: 1) == 1
    assert _results_kept(out) == []


def test_a_broken_file_is_computed_again(pair_out: Path, tmp_path: Path):
    out = _copy(pair_out, tmp_path / "out")
    _results.kept_result(out, "n", (), lambda: 1)
    (name,) = _results_kept(out)
    for data in (b"", b"not arrow", b"ARROW1" + os.urandom(100)):
        (out / METRIC_CACHE_DIR / name).write_bytes(data)
        assert _results.kept_result(out, "n", (), lambda: 2) == 2
        assert _results.kept_result(out, "n", (), lambda: 3) == 2  # written again, then read


def test_a_forged_deep_shape_is_not_read(pair_out: Path, tmp_path: Path):
    out = _copy(pair_out, tmp_path / "out")
    _results.kept_result(out, "n", (), lambda: 1)
    (name,) = _results_kept(out)
    deep = ("[" * 200_000 + "]" * 200_000).encode()  # 400 KB, far past Python's recursion
    table = pa.table({"frame": pa.array([], pa.large_binary())})
    table = table.replace_schema_metadata({b"vge-result": deep})
    sink = pa.BufferOutputStream()
    with pa.ipc.new_file(sink, table.schema) as writer:
        writer.write_table(table)
    (out / METRIC_CACHE_DIR / name).write_bytes(sink.getvalue().to_pybytes())
    assert _results.kept_result(out, "n", (), lambda: 2) == 2


def test_no_result_kept_without_a_manifest(pair_out: Path, tmp_path: Path):
    out = _copy(pair_out, tmp_path / "out")
    (out / "manifest.json").unlink()
    assert _results.kept_result(out, "n", (), lambda: 1) == 1
    assert _results_kept(out) == []
