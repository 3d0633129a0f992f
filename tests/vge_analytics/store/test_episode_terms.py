"""The terms kept per (run, episode) (`store._episode_terms`, docs/METRICS.md): the intervals
they give are the tables' to the bit, the file is what answers, another content of OUT or
another definition names another file, and a file that is not one of ours is not read."""

from __future__ import annotations

from pathlib import Path

import polars as pl
import pytest

import vge_analytics as va
from replay.io import METRIC_CACHE_DIR
from tests.vge_analytics.store.kept import copy_out, kept_files, plants
from vge_analytics.reports.inference import _intervals
from vge_analytics.store import _episode_terms, episodes
from vge_analytics.store import _kept as kept_module

CHOICES = (
    ("SR", ("run_id", "model"), None),
    ("SR", ("model",), {"category": ["Microwave", "AirFryer"]}),
    ("SR", ("category",), {"n_goals": [1, 2]}),
    ("SPL", ("n_goals",), {"run_id": ["sim-human", "sim-vlm-a"]}),
    ("VSPS", ("agent_kind",), {"model": "sim-vlm-f"}),
    ("EIR", ("run_id",), None),
    ("AvgDist", ("model",), {"category": "Microwave", "meta_history_length": ["0", "3"]}),
    ("PSR", ("n_goals",), {"agent_kind": "vlm"}),
    ("State-F1", ("run_id",), None),
    ("GVPE", ("model",), {"category": "Microwave", "agent_kind": ["vlm"]}),
    ("StepsToRecover", ("run_id", "model"), None),
)


_copy = copy_out


def _kept(out: Path) -> list[str]:
    return [p.name for p in kept_files(out, "terms_*")]


def _direct(out: Path, monkeypatch, **choice) -> pl.DataFrame:
    """The interval from the tables alone (the kept terms refused)."""
    with monkeypatch.context() as patch:
        patch.setattr(_intervals, "kept_episode_terms", lambda *a, **k: None)
        return va.metric_intervals(out, resamples=200, **choice)


def _interval(out: Path, **choice) -> pl.DataFrame:
    return va.metric_intervals(out, resamples=200, **choice)


def test_kept_terms_give_the_tables_intervals_on_the_sample(
    sample_out: Path, tmp_path: Path, monkeypatch
):
    out = _copy(sample_out, tmp_path / "out")
    for metric, by, where in CHOICES:
        for cluster in ("device", "category"):
            choice = dict(metric=metric, by=by, where=where, cluster=cluster)
            want = _direct(out, monkeypatch, **choice)
            first = _interval(out, **choice)  # computes and keeps the grain's terms
            again = _interval(out, **choice)  # reads them
            assert first.equals(want) and first.schema == want.schema, choice
            assert again.equals(want) and again.schema == want.schema, choice
    # one file per metric, named by its grain
    grains = sorted({va.MetricSet.builtin().get(m).grain for m, _, _ in CHOICES})
    assert sorted({n.split("-")[0] for n in _kept(out)}) == [f"terms_{g}" for g in grains]
    assert len(_kept(out)) == len({m for m, _, _ in CHOICES})


def test_a_column_not_kept_is_answered_from_the_tables(pair_out: Path, tmp_path: Path):
    out = _copy(pair_out, tmp_path / "out")
    store = va.open_store(out)
    (sr,) = va.MetricSet.builtin().resolve(["SR"])
    assert _episode_terms.kept_episode_terms(store, sr, ["termination"], None) is None
    assert _kept(out) == []  # nothing computed for a question it cannot answer
    rows = _episode_terms.kept_episode_terms(store, sr, ["model"], {"run_id": "A"})
    assert rows is not None and rows["run_id"].unique().to_list() == ["A"]
    assert rows.columns == ["run_id", "episode_id", "device_id", "category", "n_goals"] + [
        "SR:num",
        "SR:den",
    ]
    assert rows.height == 10 and rows["SR:num"].sum() == 2  # 2 of A's 10 succeed


def _terms_file(out: Path, grain: str = "episodes") -> Path:
    (name,) = [n for n in _kept(out) if n.startswith(f"terms_{grain}-")]
    return out / METRIC_CACHE_DIR / name


def test_the_kept_file_is_what_answers(pair_out: Path, tmp_path: Path):
    """Every SR numerator of the file set to 0: the next interval says SR 0, so the file is
    read; the tables still say 20 and 63.6."""
    out = _copy(pair_out, tmp_path / "out")
    before = _interval(out, by=["run_id"])
    assert before["value"].to_list() == pytest.approx([20.0, 700 / 11])
    path = _terms_file(out)
    pl.read_parquet(path).with_columns(pl.lit(0).alias("SR:num")).write_parquet(path)
    va.clear_cache()
    assert _interval(out, by=["run_id"])["value"].to_list() == [0.0, 0.0]


def test_a_run_replayed_again_names_another_file(pair_out: Path, tmp_path: Path):
    """A table file changed (another content of OUT): the terms are computed again, from the
    tables as they are now, and the file of the old contents is removed."""
    out = _copy(pair_out, tmp_path / "out")
    _interval(out, by=["run_id"])
    old = _kept(out)
    (part,) = sorted((out / "episodes" / "run_id=A").glob("*.parquet"))
    frame = pl.read_parquet(part).with_columns(pl.lit(True).alias("success"))
    frame.write_parquet(part)
    va.clear_cache()
    got = _interval(out, by=["run_id"])
    assert got["value"].to_list() == pytest.approx([100.0, 700 / 11])
    new = _kept(out)
    assert len(new) == 1 and new != old


def test_a_changed_metric_file_names_another_file(pair_out: Path, tmp_path: Path):
    out = _copy(pair_out, tmp_path / "out")
    folder = tmp_path / "metrics"
    folder.mkdir()
    text = (Path(va.__file__).parent / "sql" / "sr.sql").read_text()
    (folder / "sr.sql").write_text(text)
    got = _interval(out, by=["run_id"], metrics_dir=folder)
    assert got["value"].to_list() == pytest.approx([20.0, 700 / 11])
    (folder / "sr.sql").write_text(text.replace("(WHERE success)", "(WHERE NOT success)"))
    got = _interval(out, by=["run_id"], metrics_dir=folder)
    assert got["value"].to_list() == pytest.approx([80.0, 400 / 11])
    assert len(_kept(out)) == 2


def test_files_past_the_bound_are_removed(pair_out: Path, tmp_path: Path, monkeypatch):
    monkeypatch.setattr(_episode_terms, "MAX_TERMS_FILES", 2)
    out = _copy(pair_out, tmp_path / "out")
    folder = tmp_path / "metrics"
    folder.mkdir()
    text = (Path(va.__file__).parent / "sql" / "sr.sql").read_text()
    for k in range(4):  # four definitions of SR: four files of the episodes' grain
        (folder / "sr.sql").write_text(
            text.replace("(WHERE success)", f"(WHERE success OR {k} < 0)")
        )
        _interval(out, by=["run_id"], metrics_dir=folder)
    assert len(_kept(out)) == 2


PLANTS, PLANT_IDS = plants("SR:num")


@pytest.mark.parametrize("plant", PLANTS, ids=PLANT_IDS)
def test_a_file_that_is_not_ours_is_computed_again(
    pair_out: Path, tmp_path: Path, monkeypatch, plant
):
    out = _copy(pair_out, tmp_path / "out")
    want = _interval(out, by=["run_id"])
    path = _terms_file(out)
    plant(path, tmp_path)  # a link's target says SR 0: never read
    va.clear_cache()
    assert _interval(out, by=["run_id"]).equals(want)
    assert _interval(out, by=["run_id"]).equals(_direct(out, monkeypatch, by=["run_id"]))
    assert path.is_file() and not path.is_symlink()  # written again, whole, in its place


def test_a_file_over_the_bound_is_not_read(pair_out: Path, tmp_path: Path, monkeypatch):
    out = _copy(pair_out, tmp_path / "out")
    want = _interval(out, by=["run_id"])
    path = _terms_file(out)
    pl.read_parquet(path).with_columns(pl.lit(0).alias("SR:num")).write_parquet(path)
    monkeypatch.setattr(_episode_terms, "MAX_TERMS_BYTES", 100)
    va.clear_cache()
    assert _interval(out, by=["run_id"]).equals(want)


def test_nothing_is_kept_where_out_cannot_be_written(pair_out: Path, tmp_path: Path, monkeypatch):
    out = _copy(pair_out, tmp_path / "out")

    def refuse(*args, **kwargs):
        raise PermissionError(13, "Read-only file system")

    monkeypatch.setattr(kept_module, "atomic_file", refuse)
    assert _interval(out, by=["run_id"]).equals(_direct(out, monkeypatch, by=["run_id"]))
    assert _kept(out) == []


def test_the_metric_cache_keeps_the_episodes_terms_with_the_runs(pair_out: Path, tmp_path: Path):
    """`vge metrics OUT` (the per-run terms written) also keeps the episodes' terms per
    episode, which the Leaderboard's first interval (SR's) reads."""
    out = _copy(pair_out, tmp_path / "out")
    va.metrics(out, by="run_id")
    assert [n.split("-")[0] for n in _kept(out)] == ["terms_episodes"]
    assert pl.read_parquet(_terms_file(out)).height == 21  # 10 episodes of A, 11 of B


def test_the_file_written_in_parts_holds_the_rows_and_types_of_the_tables(
    sample_out: Path, tmp_path: Path, monkeypatch
):
    """Each run a part of its own (`EPISODES_PER_QUERY` 1): for every built-in metric, the
    kept file holds the rows the tables' path joins (`episode_terms` joined to the
    episodes, the frame the file was written from before), with their columns and types."""
    monkeypatch.setattr(_episode_terms, "EPISODES_PER_QUERY", 1)
    out = _copy(sample_out, tmp_path / "out")
    store = va.open_store(out)
    held = _episode_terms._held(store)
    parts = _episode_terms._run_parts(store)
    assert len(parts) == len(store.manifest["runs"]) > 1
    keys = ["run_id", "episode_id"]
    builtin = va.MetricSet.builtin()
    rows = episodes(store, None, columns=[*keys, *held])
    for ratio in builtin.resolve(list(builtin.metrics)):
        path = _episode_terms._keep(store, ratio, held, ())
        assert path is not None and path.is_file(), ratio.name
        streamed = pl.read_parquet(path)
        names = [f"{ratio.name}:num", f"{ratio.name}:den"]
        terms = va.episode_terms(out, [ratio.name])
        tables = rows.join(terms, on=keys, how="inner").select([*keys, *held, *names])
        tables.write_parquet(tmp_path / "whole.parquet")  # as the frame was kept
        assert streamed.schema == pl.read_parquet(tmp_path / "whole.parquet").schema, ratio.name
        assert streamed.schema == tables.schema, ratio.name
        assert streamed.equals(streamed.sort(keys)), ratio.name  # kept as an interval sorts
        assert streamed.equals(tables.sort(keys)), ratio.name
        assert streamed.height == tables.height > 0


def test_a_part_that_fails_leaves_nothing(pair_out: Path, tmp_path: Path, monkeypatch):
    """The second part's query fails: no file is kept (not half of one, no temporary file),
    `vge metrics` still answers, and an interval is answered from the tables."""
    monkeypatch.setattr(_episode_terms, "EPISODES_PER_QUERY", 1)
    out = _copy(pair_out, tmp_path / "out")
    compute = _episode_terms._compute
    calls = []

    def second_fails(*args, **kwargs):
        calls.append(args[-1])
        if len(calls) == 2:
            raise va.QueryError("the second part failed")
        return compute(*args, **kwargs)

    monkeypatch.setattr(_episode_terms, "_compute", second_fails)
    va.metrics(out, by="run_id")
    assert calls == [["A"], ["B"]]
    assert _kept(out) == []
    assert [p.name for p in (out / METRIC_CACHE_DIR).iterdir() if p.name.startswith(".")] == []
    monkeypatch.setattr(_episode_terms, "_compute", compute)
    assert _interval(out, by=["run_id"]).equals(_direct(out, monkeypatch, by=["run_id"]))
