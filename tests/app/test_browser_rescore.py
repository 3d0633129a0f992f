"""End to end: `vge app OUT --metrics-dir DIR` in Chromium. The leaderboard shows the folder's
metrics (an overridden one marked ✎, an added one +), and the Rescore page shows what they
change, as the analytics API computes it.

A server of its own (the session's `app_server` runs with the built-in metrics), in the
browser group with the other browser tests.
"""

from __future__ import annotations

import pytest

import vge_analytics as va

from .conftest import ARTIFACTS
from .streamlit_browser import AppPage, served

pytestmark = pytest.mark.xdist_group("browser")


@pytest.fixture(scope="module")
def rescore_server(tiny_out, metrics_folder, tmp_path_factory):
    log = tmp_path_factory.mktemp("server") / "vge-app-metrics.log"
    options = ["--metrics-dir", str(metrics_folder)]
    with served(tiny_out, options=options, log=log) as server:
        yield server


def test_metrics_folder_in_chromium(page, rescore_server, tiny_out, metrics_folder):
    browser = AppPage(page, rescore_server.url)
    expected = va.metrics(tiny_out, metrics_dir=metrics_folder)

    browser.open("", "Per metric")
    browser.screenshot(ARTIFACTS / "app-leaderboard-metrics-dir.png")
    assert not browser.errors(), browser.errors()
    assert "✎ overridden: SR; + added: SR-multi" in browser.text()
    header, *rows = browser.tables()[0]
    assert "SR ↑ ✎" in header and "SR-multi ↑ +" in header
    shown = {row[0]: dict(zip(header, row, strict=False)) for row in rows}
    for row in expected.iter_rows(named=True):
        assert float(shown[row["run_id"]]["SR ↑ ✎"]) == pytest.approx(row["SR"], abs=0.005)

    result = va.rescore(tiny_out, metrics_folder, by=("run_id", "model"))
    browser.navigate("/rescore", "Kendall")
    browser.screenshot(ARTIFACTS / "app-rescore.png")
    assert not browser.errors(), browser.errors()
    rankings, changes = browser.tables()[:2]
    assert rankings[1][:2] == ["SR", "changed"]
    tau = result.summary["kendall_tau_b"][0]
    assert float(rankings[1][rankings[0].index("Kendall τ-b")]) == pytest.approx(tau, abs=0.005)
    sr = result.rows.filter(result.rows["metric"] == "SR")
    groups = [row[changes[0].index("group")] for row in changes[1:]]
    assert groups == sr["run_id"].to_list()[: len(groups)]
    assert not browser.page_errors, browser.page_errors
