"""End to end: the Leaderboard in Chromium on four priced runs of the kettle benchmark
(`test_leaderboard_costs.priced_out`: run c has no cost, run d is cut short), with a metrics
folder that overrides SR and adds SR-multi (for which no run has an episode of several goals:
a missing value in every row).

The grid is a canvas: the test records the text it draws (`fillText`, with the font and
the width the browser measures) to see what a person sees: a missing value drawn as `–`,
never `None`; the cost columns drawn on first sight, without scrolling sideways; every
label narrower than the column sized for it (`dash.text_width`).
"""

from __future__ import annotations

import pytest

from vge_analytics import dashboard as dash
from vge_analytics.reports import MISSING

from .conftest import ARTIFACTS
from .streamlit_browser import AppPage, served
from .test_leaderboard_costs import kettle_bench, priced_out  # noqa: F401

pytestmark = pytest.mark.xdist_group("browser")

_RECORD_JS = """() => {
  window.__drawn = new Map();
  const fill = CanvasRenderingContext2D.prototype.fillText;
  CanvasRenderingContext2D.prototype.fillText = function (text, x, y, ...rest) {
    window.__drawn.set(String(text), this.measureText(String(text)).width);
    return fill.call(this, text, x, y, ...rest);
  };
}"""
_DRAWN_JS = "() => Object.fromEntries(window.__drawn || [])"


def test_leaderboard_in_chromium(page, priced_out, metrics_folder, tmp_path):  # noqa: F811
    page.add_init_script(f"({_RECORD_JS})()")
    options = ["--metrics-dir", str(metrics_folder)]
    with served(priced_out, options=options, log=tmp_path / "vge-app.log") as server:
        browser = AppPage(page, server.url)
        browser.open("", "Per metric")
        browser.screenshot(ARTIFACTS / "app-leaderboard-costs.png")
        assert not browser.errors(), browser.errors()
        header, *rows = browser.tables()[0]
        drawn: dict[str, float] = page.evaluate(_DRAWN_JS)

    # The cost columns come right after the labels: drawn without scrolling sideways.
    assert header[:4] == ["group", "model", "$ / episode", "$ / success"]
    assert [row[0] for row in rows] == ["a", "b", "c", "d (incomplete)"]
    assert "$0.0015" in drawn and "SR ↑ ✎" in drawn
    # Missing values (c's cost, d's cost per success, SR-multi everywhere, the intervals of
    # one-device runs) are drawn as the command line writes them.
    assert MISSING in drawn
    assert "None" not in drawn and "nan" not in drawn
    # Every label and header fits in the width the table gives it (8 px a character
    # bounds the browser's own measure of the drawn text).
    for text in ("d (incomplete)", "model-d", "$ / episode", "$ / success", "group"):
        assert drawn[text] + 12 <= dash.text_width(text), (text, drawn[text])  # 12: the padding
