"""The words around the command line's tables (`reports`): how a missing value reads, and
the title of a table of metrics, which names what a metrics folder changed instead of
calling every column the paper's."""

from __future__ import annotations

from pathlib import Path

import polars as pl

import vge_analytics as va
from vge_analytics import reports
from vge_analytics.cli import main

from ..metrics.metric_files import SR_AS_SSR, SR_MULTI, write_folder


def test_the_title_names_what_a_folder_changes(tmp_path: Path) -> None:
    assert reports.metrics_held(["SR", "SPL"]) == "The paper's metrics"
    folder = write_folder(tmp_path / "mine", {"sr.sql": SR_AS_SSR, "multi.sql": SR_MULTI})
    mine = va.load_metrics(folder)
    by = f"by {folder}"
    assert reports.metrics_held(["SPL", "VSPS"], mine) == "The paper's metrics"
    assert reports.metrics_held(["SR", "SPL"], mine) == f"The paper's metrics, SR overridden {by}"
    assert reports.metrics_held(["SPL", "SR-multi"], mine) == (
        f"The paper's metrics, SR-multi added {by}"
    )
    assert reports.metrics_held(["SR", "SPL", "SR-multi"], mine) == (
        f"The paper's metrics, SR overridden and SR-multi added {by}"
    )
    # Nothing of the paper's left: the title does not claim it.
    assert reports.metrics_held(["SR", "SR-multi"], mine) == (
        f"Metrics: SR overridden and SR-multi added {by}"
    )
    assert reports.metrics_held(["SR-multi"], mine) == f"Metrics: SR-multi added {by}"


def test_vge_metrics_title_with_a_folder(capsys, hand_out: Path, tmp_path: Path) -> None:
    folder = write_folder(tmp_path / "mine", {"multi.sql": SR_MULTI})
    code = main(["metrics", str(hand_out), "--metrics", "SR-multi", "--metrics-dir", str(folder)])
    out = capsys.readouterr().out
    assert code == 0
    title = "".join(out.split("┏")[0].split())  # rich wraps the title at the table's width
    expected = f"Metrics: SR-multi added by {folder}: {reports.ARROWS_LEGEND}"
    assert title == "".join(expected.split())
    assert "The paper's metrics" not in out


def test_a_missing_value_reads_as_a_dash() -> None:
    assert reports.MISSING == "\u2013"
    df = pl.DataFrame({"run_id": ["a", "b"], "SR": [50.0, None], "SPL": [float("nan"), 1.0]})
    text = reports.render_markdown(df)
    assert "| b | \u2013 | 1.00 |" in text and "| a | 50.00 | \u2013 |" in text
    assert "None" not in text and "nan" not in text
