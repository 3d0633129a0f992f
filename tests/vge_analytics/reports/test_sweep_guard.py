"""A metric file in a sweep meets the guard and limits it meets in `vge metrics`: the sweep's
in-memory tables are a store of their own (`store.memory_store`) on the same locked connection,
and its queries go through the same door (`store.guarded_cursor`)."""

from __future__ import annotations

import contextlib
from pathlib import Path

import pyarrow as pa

import replay
import vge_analytics as va
from vge_analytics.cli import main
from vge_analytics.store import SqlLimits, memory_store, run_query

from ..metrics.metric_files import RUNAWAY, metric_text, write_folder

GUARDED = metric_text(
    "Guarded",
    # Counts an episode only when its query runs where no file can be opened and no setting
    # changed: what the store's connection promises (docs/METRICS.md). A connection of
    # DuckDB's defaults (the sweep's own, before) counts none.
    "count(*) FILTER (WHERE (SELECT count(*) FROM duckdb_settings() WHERE "
    "(name = 'enable_external_access' AND value = 'false') OR "
    "(name = 'lock_configuration' AND value = 'true')) = 2)",
    "count(*)",
    definition="The share of episodes whose query ran on a locked connection.",
)


def test_a_metric_file_in_a_sweep_runs_on_the_locked_connection(
    hand_out: Path, tmp_path: Path
) -> None:
    folder = write_folder(tmp_path / "guarded", {"guarded.sql": GUARDED})
    # In `vge metrics`: every episode's query ran on the locked connection.
    assert va.metrics(hand_out, metrics=["Guarded"], metrics_dir=folder)["Guarded"].to_list() == [
        100.0,
        100.0,
    ]
    # In a sweep, at each lambda, the same.
    swept = va.sweep(hand_out, [2, 5], metrics=["Guarded"], metrics_dir=folder)
    assert swept.height == 4
    assert swept["Guarded"].to_list() == [100.0] * 4


def test_a_runaway_metric_in_a_sweep_stops_at_the_time_limit(
    capsys, hand_out: Path, tmp_path: Path
) -> None:
    folder = write_folder(tmp_path / "runaway", {"runaway.sql": RUNAWAY})
    code = main(
        ["sweep", str(hand_out), "--lambdas", "5", "--metrics", "Runaway"]
        + ["--metrics-dir", str(folder), "--timeout", "0.5"]
    )
    assert code == 1
    # One line, naming the metric file, as `vge metrics` says it (test_user_metrics.py).
    assert capsys.readouterr().err == (
        f"error: {folder / 'runaway.sql'}: the query of this metric file ran past its time "
        "limit of 0.5 s and was stopped (--timeout sets the limit)\n"
    )


def test_a_memory_store_has_the_limits_of_an_out_store(hand_out: Path) -> None:
    episodes = replay.arrow_schema(replay.EpisodeRow).empty_table()
    limits = SqlLimits.make(memory="64MB")
    with contextlib.closing(
        memory_store({"episodes": episodes}, label=hand_out, limits=limits)
    ) as store:
        settings = run_query(
            store,
            "SELECT name, value FROM duckdb_settings() WHERE name IN "
            "('memory_limit', 'max_temp_directory_size', 'enable_external_access') ORDER BY name",
            [],
        )
        assert settings.rows() == [
            ("enable_external_access", "false"),
            ("max_temp_directory_size", "128.0 MiB"),
            ("memory_limit", "64.0 MiB"),
        ]
        # The tables not given are there, empty, with the replay's columns.
        assert store.columns["steps"] == {
            f.name: store.columns["steps"][f.name]
            for f in replay.arrow_schema(replay.StepRow)
        }
        assert run_query(store, "SELECT count(*) AS n FROM goals", [])["n"].to_list() == [0]
        assert isinstance(store.sources["episodes"], pa.Table)
