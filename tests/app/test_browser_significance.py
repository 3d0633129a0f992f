"""End to end: the Significance page in Chromium (Playwright), on the tiny benchmark with
repeated runs (`seeded_out`): its ranking with the tied groups, the pairwise matrix and the
pass@k / pass^k curves, as the analytics API computes them.

A server of its own, in the browser group with the other browser tests.
"""

from __future__ import annotations

import pytest

import vge_analytics as va

from .conftest import ARTIFACTS
from .streamlit_browser import AppPage, served

pytestmark = pytest.mark.xdist_group("browser")


@pytest.fixture(scope="module")
def seeded_server(seeded_out, tmp_path_factory):
    log = tmp_path_factory.mktemp("server") / "vge-app-seeded.log"
    with served(seeded_out, log=log) as server:
        yield server


def test_significance_page_in_chromium(page, seeded_server, seeded_out):
    expected = va.compare_all(seeded_out)
    repeated = va.repeated(seeded_out)
    browser = AppPage(page, seeded_server.url)
    browser.open("significance", "pass@k")
    browser.screenshot(ARTIFACTS / "app-significance.png", full_page=True)
    assert not browser.errors(), browser.errors()
    text = browser.text()
    assert "Traceback" not in text
    assert f"{expected.pairs.height} pairs of {expected.ranking.height} run_id values" in text
    ranking = browser.table_with(["rank", "run_id"], index=0)
    header, *rows = ranking
    shown = {row[header.index("run_id")]: row[header.index("letters")] for row in rows}
    assert shown == dict(zip(expected.ranking["run_id"], expected.ranking["letters"], strict=True))
    groups = next(t for t in browser.tables() if t[0][:2] == ["group", "runs"])
    multi = repeated.groups.filter(repeated.groups["n_runs"] >= 2)
    assert [row[0] for row in groups[1:]] == multi["group"].to_list()
    sr = [float(row[groups[0].index("SR mean")]) for row in groups[1:]]
    assert sr == pytest.approx(multi["SR_mean"].to_list(), abs=0.005)
    assert page.locator("canvas, svg.marks").count() >= 2  # the matrix and the curves
    assert not browser.page_errors, browser.page_errors
