"""The step counts of a new content of OUT count only the runs whose files changed
(`store._run_keys`, `_step_counts._recounted`): a run replayed into OUT, replayed again or
changed by hand is counted, a removed run's rows go, every other run's rows are the kept
file's, and the rows are those of a count of everything; a kept file that is not one of ours
is counted whole again."""

from __future__ import annotations

import gzip
import json
import shutil
from pathlib import Path

import polars as pl
import pytest

import replay
import vge_analytics as va
from tests.vge_analytics.conftest import LOGS, replay_to
from tests.vge_analytics.store.kept import copy_out, kept_files
from vge_analytics.store import _kept, _run_keys, _scan_counts, _step_counts, open_store

TWO = ("sim-human", "sim-vlm-a")


@pytest.fixture(scope="module")
def two_out(tmp_path_factory) -> Path:
    """Two runs of the bundled sample replayed."""
    root = tmp_path_factory.mktemp("two")
    return replay_to(root / "out", [LOGS / "runs" / r for r in TWO], LOGS / "bench")


def _replay(out: Path, *runs: Path) -> None:
    replay.replay_runs([str(r) for r in runs], str(LOGS / "bench"), str(out), progress=False)
    va.clear_cache()


def _counts(out: Path) -> dict[str, pl.DataFrame]:
    """Each part's kept counts of OUT as the pages get them (kept first when missing)."""
    store = open_store(out)
    return {name: _step_counts._counts(store, name) for name in _step_counts.PARTS}


def _everything(out: Path) -> dict[str, pl.DataFrame]:
    """Each part counted from all of OUT's files (nothing kept is read)."""
    store = open_store(out)
    return {name: _step_counts._counted(store, part) for name, part in _step_counts.PARTS.items()}


def _same(got: dict[str, pl.DataFrame], want: dict[str, pl.DataFrame]) -> None:
    for name in _step_counts.PARTS:
        assert got[name].equals(want[name]), name
        assert got[name].schema == want[name].schema, name


@pytest.fixture
def counted(monkeypatch) -> dict[str, list]:
    """What was counted: the runs asked of `count_steps` (None: all), the files polars'
    process was given to read, the queries DuckDB ran."""
    seen: dict[str, list] = {"runs": [], "files": [], "queries": []}
    real_count, real_chunks = _step_counts.count_steps, _scan_counts._chunks
    real_query = _step_counts.run_query

    def count(*args):
        seen["runs"].append(None if args[5] is None else sorted(args[5]))
        return real_count(*args)

    def chunks(runs):  # what the count's process is handed to read (it reads there)
        cut = real_chunks(runs)
        seen["files"].extend(path for _, paths in cut for path in paths)
        return cut

    monkeypatch.setattr(_step_counts, "count_steps", count)
    monkeypatch.setattr(_scan_counts, "_chunks", chunks)
    monkeypatch.setattr(
        _step_counts, "run_query", lambda *a: seen["queries"].append(a[2]) or real_query(*a)
    )
    return seen


def _folders(files: list[str]) -> set[str]:
    return {Path(f).parent.name for f in files}


def test_a_run_replayed_into_out_is_the_only_one_counted(two_out: Path, tmp_path: Path, counted):
    out = copy_out(two_out, tmp_path / "out")
    before = _counts(out)
    assert counted["runs"] == [None] * 3 and _folders(counted["files"]) == {
        "run_id=sim-human",
        "run_id=sim-vlm-a",
    }
    _replay(out, LOGS / "runs" / "sim-vlm-b")
    for what in counted.values():
        what.clear()
    after = _counts(out)
    assert counted["runs"] == [["sim-vlm-b"]] * 3  # each part: the new run alone
    assert _folders(counted["files"]) == {"run_id=sim-vlm-b"} and counted["queries"] == []
    _same(after, _everything(out))
    for name, frame in after.items():  # the other runs' rows are the kept ones
        old = frame.filter(pl.col("run_id") != "sim-vlm-b")
        assert old.equals(before[name]) and set(frame["run_id"]) == {*TWO, "sim-vlm-b"}
    assert len(kept_files(out, "counts_*")) == 3  # the earlier content's files pruned
    va.clear_cache()
    assert _counts(out)["views"].equals(after["views"])  # read as before: no count


def _fewer_episodes(run: str, target: Path) -> Path:
    """A copy of the sample's run `run` whose log holds its first half of episodes only."""
    shutil.copytree(LOGS / "runs" / run, target)
    log = target / "episodes.jsonl.gz"
    lines = gzip.decompress(log.read_bytes()).splitlines(keepends=True)
    log.write_bytes(gzip.compress(b"".join(lines[: len(lines) // 2])))
    return target


def test_a_run_replayed_again_from_other_logs_is_counted_again(
    two_out: Path, tmp_path: Path, counted
):
    out = copy_out(two_out, tmp_path / "out")
    before = _counts(out)
    _replay(out, _fewer_episodes("sim-vlm-a", tmp_path / "sim-vlm-a"))
    counted["runs"].clear()
    after = _counts(out)
    assert counted["runs"] == [["sim-vlm-a"]] * 3
    _same(after, _everything(out))
    errors = after["errors"].filter(pl.col("run_id") == "sim-vlm-a")["scored"].sum()
    assert 0 < errors < before["errors"].filter(pl.col("run_id") == "sim-vlm-a")["scored"].sum()
    human = [f.filter(pl.col("run_id") == "sim-human") for f in (before["errors"], after["errors"])]
    assert human[0].equals(human[1])


def _drop_run(out: Path, run: str) -> None:
    """Take `run` out of OUT: from its manifest, its tables' folders and the runs table."""
    manifest = json.loads((out / "manifest.json").read_text())
    manifest["runs"] = [r for r in manifest["runs"] if r["run_id"] != run]
    (out / "manifest.json").write_text(json.dumps(manifest))
    for table in ("steps", "episodes", "goals"):
        shutil.rmtree(out / table / f"run_id={run}")
    (runs,) = (out / "runs").glob("*.parquet")
    pl.read_parquet(runs).filter(pl.col("run_id") != run).write_parquet(runs)
    va.clear_cache()


def test_a_removed_runs_rows_go_and_nothing_is_counted(two_out: Path, tmp_path: Path, counted):
    out = copy_out(two_out, tmp_path / "out")
    before = _counts(out)
    _drop_run(out, "sim-human")
    counted["runs"].clear()
    after = _counts(out)
    assert counted["runs"] == [] and counted["queries"] == []
    _same(after, _everything(out))
    for name, frame in after.items():
        assert frame.equals(before[name].filter(pl.col("run_id") == "sim-vlm-a"))


def test_a_file_changed_by_hand_is_counted_again(two_out: Path, tmp_path: Path, counted):
    out = copy_out(two_out, tmp_path / "out")
    _counts(out)
    (part,) = (out / "steps" / "run_id=sim-human").glob("*.parquet")
    frame = pl.read_parquet(part)
    frame.head(frame.height - 40).write_parquet(part)
    va.clear_cache()
    counted["runs"].clear()
    after = _counts(out)
    assert counted["runs"] == [["sim-human"]] * 3
    _same(after, _everything(out))


def test_a_file_listed_by_another_run_is_counted_as_that_runs(
    two_out: Path, tmp_path: Path, counted
):
    out = copy_out(two_out, tmp_path / "out")
    _replay(out, LOGS / "runs" / "sim-vlm-b")
    before = _counts(out)
    manifest = json.loads((out / "manifest.json").read_text())
    human, vlm = (r for r in manifest["runs"] if r["run_id"] in TWO)
    vlm["outputs"]["steps"] += human["outputs"]["steps"]  # its rows now sim-vlm-a's
    human["outputs"]["steps"] = []
    (out / "manifest.json").write_text(json.dumps(manifest))
    va.clear_cache()
    counted["runs"].clear()
    counted["queries"].clear()
    after = _counts(out)
    assert counted["runs"] == [["sim-vlm-a"]] * 3  # sim-human has no file: its rows gone
    assert counted["queries"] == [["sim-vlm-a"]] * 3  # (a file out of its folder: DuckDB)
    _same(after, _everything(out))
    assert set(after["errors"]["run_id"]) == {"sim-vlm-a", "sim-vlm-b"}
    total = after["errors"]["scored"].sum()
    assert total == before["errors"]["scored"].sum()


def test_the_runs_counted_again_by_duckdb_are_those_alone(
    two_out: Path, tmp_path: Path, counted, monkeypatch
):
    out = copy_out(two_out, tmp_path / "out")
    _counts(out)
    _replay(out, LOGS / "runs" / "sim-vlm-b")
    monkeypatch.setattr(_scan_counts, "_runs", lambda store: None)  # polars cannot: DuckDB
    counted["queries"].clear()
    after = _counts(out)
    assert counted["queries"] == [["sim-vlm-b"]] * 3  # the query's one bound run
    _same(after, _everything(out))


def _keys(path: Path, keys: dict[str, str]) -> None:
    """Write `path` again with `keys` as its runs' keys."""
    footer = {_run_keys.RUN_KEYS: json.dumps(keys)}
    _kept.keep_parts(path, [pl.read_parquet(path)], "none", 1, footer)


def _planted(path: Path, tmp: Path) -> list:
    """Kept files of the earlier content that are not ours, or not for these runs."""
    frame = pl.read_parquet(path)
    keys = json.loads(pl.read_parquet_metadata(path)[_run_keys.RUN_KEYS])
    return [
        lambda: _keys(path, {run: "0" * 16 for run in keys}),  # other keys: all counted
        lambda: _keys(path, {"sim-vlm-a": keys["sim-vlm-a"]}),  # a run's rows without key
        lambda: _keys(path, {**keys, "sim-human": 7}),  # not a key
        lambda: frame.write_parquet(path),  # no keys kept (as BASE wrote it)
        lambda: _kept.keep_parts(
            path, [frame.rename({"scored": "other"})], "none", 1, {_run_keys.RUN_KEYS: "{}"}
        ),
        lambda: _kept.keep_parts(
            path,
            [frame.with_columns(pl.col("scored").cast(pl.String))],
            "none",
            1,
            {_run_keys.RUN_KEYS: json.dumps(keys)},
        ),
        lambda: (shutil.move(path, tmp / "elsewhere"), path.symlink_to(tmp / "elsewhere")),
    ]


@pytest.mark.parametrize("plant", range(7))
def test_a_kept_file_that_is_not_ours_is_counted_whole(
    two_out: Path, tmp_path: Path, counted, plant: int
):
    out = copy_out(two_out, tmp_path / "out")
    _counts(out)
    (path,) = kept_files(out, "counts_errors-*")
    _planted(path, tmp_path)[plant]()
    _replay(out, LOGS / "runs" / "sim-vlm-b")
    counted["runs"].clear()
    after = _counts(out)
    assert counted["runs"][0] is None  # the errors: all counted
    assert counted["runs"][1:] == [["sim-vlm-b"]] * 2  # the others' kept files are ours
    _same(after, _everything(out))


def test_a_kept_file_over_the_bound_is_not_read(
    two_out: Path, tmp_path: Path, counted, monkeypatch
):
    out = copy_out(two_out, tmp_path / "out")
    _counts(out)
    _replay(out, LOGS / "runs" / "sim-vlm-b")
    monkeypatch.setattr(_step_counts, "MAX_COUNTS_BYTES", 100)  # over it: not read
    counted["runs"].clear()
    after = _counts(out)
    assert counted["runs"] == [None] * 3
    _same(after, _everything(out))


def test_runs_added_among_the_kept_ones_fall_in_their_places(tmp_path: Path, counted):
    runs = LOGS / "runs"
    out = replay_to(tmp_path / "out", [runs / "sim-human", runs / "sim-vlm-b"], LOGS / "bench")
    _counts(out)
    _replay(out, runs / "sim-vlm-a", runs / "sim-vlm-f")  # one between the two, one after
    counted["runs"].clear()
    after = _counts(out)
    assert counted["runs"] == [["sim-vlm-a", "sim-vlm-f"]] * 3
    _same(after, _everything(out))


@pytest.mark.parametrize(
    "fresh", [[], ["r00"], ["r03", "r50", "r99"], [f"r{i:02}" for i in range(0, 100, 2)]]
)
def test_the_merged_rows_are_sorted_as_a_count_of_all(fresh: list[str]):
    rows = [(f"r{i:02}", c, (i * 7 + ord(c)) % 5) for i in range(100) for c in "zab"]
    whole = pl.DataFrame(
        rows, schema={"run_id": pl.String, "category": pl.String, "n": pl.Int64}, orient="row"
    )
    kept = whole.filter(~pl.col("run_id").is_in(fresh))
    counted = whole.filter(pl.col("run_id").is_in(fresh))
    merged = _step_counts._merged(kept, counted)
    assert merged.equals(whole)  # each run's rows in their own (unsorted) order
