"""The metric cache (`store._cache`, docs/METRICS.md): the same values as the tables give, a
file that is really read, and a new file when OUT or a metric's definition changes."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq
import pytest

import vge_analytics as va
from replay.io import METRIC_CACHE_DIR
from tests.vge_analytics.conftest import replay_to
from tests.vge_analytics.store.kept import copy_out
from vge_analytics.metrics import metric_set
from vge_analytics.store import _cache, _kept

GROUPINGS = (
    (("run_id", "model"), None),
    (("model",), None),
    (("agent_kind",), None),
    (("run_id",), None),
    ((), {"model": ["sim-vlm-a", "sim-vlm-b"]}),
    (("model",), {"run_id": ["sim-vlm-a", "sim-human"]}),
    (("category",), None),  # a column of episodes: the tables answer
    ((), None),  # no run column: the tables answer
)


_copy = copy_out  # an OUT without its cache folder


def _files(out: Path) -> list[str]:
    folder = out / METRIC_CACHE_DIR
    return sorted(p.name for p in folder.iterdir()) if folder.is_dir() else []


def test_cached_values_are_the_tables_values_on_the_sample(sample_out: Path, tmp_path: Path):
    out = _copy(sample_out, tmp_path / "out")
    for by, where in GROUPINGS:
        plain = va.metrics(out, by=by, where=where, cache=False)
        first = va.metrics(out, by=by, where=where)  # writes the cache where it answers
        again = va.metrics(out, by=by, where=where)  # reads it
        assert first.equals(plain), (by, where)
        assert again.equals(plain), (by, where)
    # One file per grain (episodes, steps, goals), the same for every grouping above, the
    # episodes' terms per episode (written with the per-run ones: the Leaderboard's SR
    # interval reads them) and the schema of each table.
    terms = [n.split("-")[0] for n in _files(out) if n.endswith(".parquet")]
    assert terms == ["episodes", "goals", "steps", "terms_episodes"]
    schemas = [n.split("-")[1] for n in _files(out) if n.endswith(".arrow")]
    assert schemas == ["episodes", "goals", "runs", "steps"]


def test_cached_values_on_synthetic_runs(pair_out: Path, hand_out: Path, tmp_path: Path):
    for k, source in enumerate((pair_out, hand_out)):
        out = _copy(source, tmp_path / f"out{k}")
        for by in (("run_id", "model"), ("agent_kind",), ("model",)):
            plain = va.metrics(out, by=by, cache=False)
            assert va.metrics(out, by=by).equals(plain), by
            assert va.metrics(out, by=by).equals(plain), by
        assert len([n for n in _files(out) if n.endswith(".parquet")]) == 4


def test_the_cache_file_is_what_answers(pair_out: Path, tmp_path: Path):
    """Rewrite the cached numerator of SR: the next call shows it, so the file is read (and
    its name is all that ties it to OUT: nothing else is checked)."""
    out = _copy(pair_out, tmp_path / "out")
    before = va.metrics(out, by="run_id", metrics="SR")
    assert before["SR"].to_list() == pytest.approx([20.0, 700 / 11])  # 2 of 10, 7 of 11
    (episodes_file,) = [n for n in _files(out) if n.startswith("episodes-")]
    path = out / METRIC_CACHE_DIR / episodes_file
    table = pq.read_table(path)
    num = table.schema.get_field_index("SR:num")
    table = table.set_column(num, "SR:num", pc.multiply(table["SR:num"], 0))
    pq.write_table(table, path)
    assert va.metrics(out, by="run_id", metrics="SR")["SR"].to_list() == [0.0, 0.0]
    assert va.metrics(out, by="run_id", metrics="SR", cache=False).equals(before)


def test_a_run_replayed_again_makes_a_new_file(pair: dict, tmp_path: Path):
    root = tmp_path / "root"
    bench = pair["bench"]
    run_a, run_b = (root / "runs" / p.name for p in pair["runs"])
    shutil.copytree(pair["runs"][0], run_a)
    shutil.copytree(pair["runs"][1], run_b)
    out = replay_to(tmp_path / "out", [run_a, run_b], bench)
    assert va.metrics(out, by="run_id", metrics="SR")["SR"].to_list() == pytest.approx(
        [20.0, 700 / 11]
    )
    old = _files(out)
    # A is played again with its first success dropped: 1 of 9 episodes.
    lines = (run_a / "episodes.jsonl").read_text().splitlines()
    (run_a / "episodes.jsonl").write_text("\n".join(lines[1:]) + "\n")
    replay_to(out, [run_a, run_b], bench)
    got = va.metrics(out, by="run_id", metrics="SR")
    assert got["SR"].to_list() == pytest.approx([100 / 9, 700 / 11])
    assert got.equals(va.metrics(out, by="run_id", metrics="SR", cache=False))
    new = _files(out)
    assert len(new) == 6 and not set(new) & set(old)  # the old files are gone


def test_a_changed_metric_file_makes_a_new_file(pair_out: Path, tmp_path: Path):
    out = _copy(pair_out, tmp_path / "out")
    folder = tmp_path / "metrics"
    folder.mkdir()
    text = (Path(va.__file__).parent / "sql" / "sr.sql").read_text()
    (folder / "sr.sql").write_text(text)
    got = va.metrics(out, by="run_id", metrics="SR", metrics_dir=folder)
    assert got["SR"].to_list() == pytest.approx([20.0, 700 / 11])
    (folder / "sr.sql").write_text(text.replace("(WHERE success)", "(WHERE NOT success)"))
    got = va.metrics(out, by="run_id", metrics="SR", metrics_dir=folder)
    assert got["SR"].to_list() == pytest.approx([80.0, 400 / 11])
    assert len([n for n in _files(out) if n.startswith("episodes-")]) == 2


def test_a_table_file_changed_by_hand_is_not_answered_from_the_cache(
    pair_out: Path, tmp_path: Path
):
    out = _copy(pair_out, tmp_path / "out")
    va.metrics(out, by="run_id", metrics="SR")
    (part,) = sorted((out / "episodes" / "run_id=A").glob("*.parquet"))
    table = pq.read_table(part)
    table = table.set_column(
        table.schema.get_field_index("success"), "success", pa.array([True] * table.num_rows)
    )
    pq.write_table(table, part)
    va.clear_cache()
    got = va.metrics(out, by="run_id", metrics="SR")
    assert got["SR"].to_list() == pytest.approx([100.0, 700 / 11])


def test_an_out_that_cannot_be_written_is_read_without_cache(
    pair_out: Path, tmp_path: Path, monkeypatch
):
    out = _copy(pair_out, tmp_path / "out")

    def refuse(*args, **kwargs):
        raise PermissionError(13, "Read-only file system")

    monkeypatch.setattr(_cache, "atomic_file", refuse)
    monkeypatch.setattr(_kept, "atomic_file", refuse)
    got = va.metrics(out, by="run_id")
    assert got.equals(va.metrics(out, by="run_id", cache=False))
    assert _files(out) == []


def test_a_broken_cache_file_is_computed_again(pair_out: Path, tmp_path: Path):
    out = _copy(pair_out, tmp_path / "out")
    want = va.metrics(out, by="run_id")
    for name in _files(out):
        (out / METRIC_CACHE_DIR / name).write_bytes(b"not parquet, not arrow")
    va.clear_cache()
    assert va.metrics(out, by="run_id").equals(want)
    for name in _files(out):
        if name.startswith("terms_"):  # a row per episode: 10 of A, 11 of B
            assert pq.read_table(out / METRIC_CACHE_DIR / name).num_rows == 21
        elif name.endswith(".parquet"):
            assert pq.read_table(out / METRIC_CACHE_DIR / name).num_rows == 2
        else:
            assert pa.ipc.read_schema(pa.py_buffer((out / METRIC_CACHE_DIR / name).read_bytes()))


def test_no_cache_without_a_manifest(pair_out: Path, tmp_path: Path):
    out = _copy(pair_out, tmp_path / "out")
    (out / "manifest.json").unlink()
    va.metrics(out, by="run_id")
    assert _files(out) == []


def test_keys_name_what_the_values_come_from(pair_out: Path):
    store = va.open_store(pair_out)
    metrics = list(metric_set(None))
    assert _cache.definitions_key(metrics) == _cache.definitions_key(list(metrics))
    assert _cache.definitions_key(metrics) != _cache.definitions_key(metrics[1:])
    assert len(store.contents) == 16 and len(store.digest) == 64


def test_an_out_opened_again_reads_no_footer_before_a_scan(pair_out: Path, tmp_path: Path):
    """The second opening builds its datasets from the kept schemas: a footer made
    unreadable after the first (its size and time kept, so OUT's key is the same) is not
    read until a query scans that file."""
    out = _copy(pair_out, tmp_path / "out")
    want = va.metrics(out, by="run_id")
    va.clear_cache()
    (part,) = sorted((out / "steps" / "run_id=A").glob("*.parquet"))
    st = part.stat()
    data = bytearray(part.read_bytes())
    data[-12:-4] = b"\xff" * 8  # the footer's length: no longer a footer
    part.write_bytes(bytes(data))
    os.utime(part, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert va.metrics(out, by="run_id").equals(want)  # the cache answers; no footer read
    with pytest.raises(va.QueryError):
        va.sql(out, "SELECT count(*) FROM steps")


def test_a_cache_folder_that_is_a_link_is_left_alone(pair_out: Path, tmp_path: Path):
    out = _copy(pair_out, tmp_path / "out")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "episodes-0-0.parquet").write_bytes(b"someone's file")
    (out / METRIC_CACHE_DIR).symlink_to(elsewhere)
    assert va.metrics(out, by="run_id").equals(va.metrics(out, by="run_id", cache=False))
    assert sorted(p.name for p in elsewhere.iterdir()) == ["episodes-0-0.parquet"]
