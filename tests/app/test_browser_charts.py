"""Charts with thirty runs, as Chromium draws them: every run is named in every chart that
shows runs, no label is cut, no legend stops early, and no two series share colour and shape.

The benchmark: the tiny synthetic one with 21 variants of its runs (`many_runs`), among
them an incomplete run (labelled `random-cut (incomplete)` on the Leaderboard) and one with
a run id longer than any label limit. The charts are read from the SVG Vega draws: axis
and legend labels (`.role-axis-label`, `.role-legend-label`), legend symbols (their fill
and path: colour and shape), and the marks, whose `aria-label` names the series they draw.
"""

from __future__ import annotations

from pathlib import Path

import pytest

import vge_analytics as va
from vge_analytics.reports import INCOMPLETE_MARK

from .conftest import ARTIFACTS
from .many_runs import INCOMPLETE_RUN_ID, LONG_RUN_ID, build_many_runs
from .streamlit_browser import AppPage, served

pytestmark = pytest.mark.xdist_group("browser")

N_RUNS = 30

# Per chart drawn as SVG: its texts, legend entries and marks (series named by aria-label).
_CHARTS_JS = """() => Array.from(
  document.querySelectorAll('[data-testid="stVegaLiteChart"]')).map(chart => {
  const svg = chart.querySelector('svg');
  if (!svg) return null;
  const texts = sel => Array.from(svg.querySelectorAll(sel)).map(t => t.textContent);
  const legend = Array.from(svg.querySelectorAll('.role-legend-entry .role-scope > g')).map(g => {
    const symbol = g.querySelector('.role-legend-symbol path');
    const label = g.querySelector('.role-legend-label text');
    return {label: label ? label.textContent : null,
            fill: symbol ? symbol.getAttribute('fill') : null,
            d: symbol ? symbol.getAttribute('d') : null,
            dash: symbol ? symbol.getAttribute('stroke-dasharray') : null};
  });
  const marks = Array.from(svg.querySelectorAll('.mark-symbol path, .mark-line path, .mark-rect path'))
    .filter(p => p.getAttribute('aria-label'))
    .map(p => ({kind: p.closest('.mark-symbol') ? 'point' : p.closest('.mark-line') ? 'line' : 'bar',
                label: p.getAttribute('aria-label'), fill: p.getAttribute('fill'),
                stroke: p.getAttribute('stroke'), d: p.getAttribute('d'),
                dash: p.getAttribute('stroke-dasharray')}));
  // Texts drawn below or right of the chart's box: the page clips them (a legend taller than
  // its plot, a chart wider than the page).
  const box = chart.getBoundingClientRect();
  const outside = Array.from(svg.querySelectorAll('text')).filter(t => {
    const r = t.getBoundingClientRect();
    return r.width > 0 && (r.bottom > box.bottom + 4 || r.right > box.right + 4);
  }).map(t => { const r = t.getBoundingClientRect();
                 return `${t.textContent} (${r.right - box.right}, ${r.bottom - box.bottom})`; });
  return {axis: texts('.role-axis-label text'), legend, marks, all: texts('text'), outside};
})"""


@pytest.fixture(scope="module")
def many_out(tmp_path_factory, cache_dir) -> Path:
    out = build_many_runs(tmp_path_factory.mktemp("many"), N_RUNS)
    yield out
    va.clear_cache()


@pytest.fixture(scope="module")
def many_server(many_out, metrics_folder, tmp_path_factory):
    """`vge app` on the thirty runs, with a metrics folder (the Rescore page)."""
    log = tmp_path_factory.mktemp("many-server") / "vge-app.log"
    options = ["--metrics-dir", str(metrics_folder)]
    with served(many_out, options=options, log=log) as server:
        yield server


def _series(label: str) -> str:
    """The series a mark draws, from its aria-label (`...; group: NAME; ...`)."""
    fields = dict(part.split(": ", 1) for part in label.split("; ") if ": " in part)
    return fields.get("group") or fields.get("run", "")


def _assert_names_every_run(chart: dict, names: list[str], where: str) -> None:
    shown = set(chart["axis"]) | {e["label"] for e in chart["legend"]}
    missing = [n for n in names if n not in shown]
    assert not missing, f"{where}: runs not named: {missing}"
    cut = [t for t in chart["all"] if "…" in t]
    assert not cut, f"{where}: labels cut: {cut}"
    assert not chart["outside"], f"{where}: drawn outside the chart: {chart['outside']}"


def _assert_series_told_apart(chart: dict, names: list[str], where: str) -> None:
    """One legend entry per run, no two with the same colour and shape; every point and
    line of a run drawn in its entry's colour, shape and dash."""
    legend = {e["label"]: e for e in chart["legend"]}
    assert sorted(legend) == sorted(names), where
    pairs = {(e["fill"], e["d"]) for e in legend.values()}
    assert len(pairs) == len(names), f"{where}: series share colour and shape"
    drawn = {name: 0 for name in names}
    for mark in chart["marks"]:
        name = _series(mark["label"])
        entry = legend[name]
        if mark["kind"] == "point":
            assert (mark["fill"], mark["d"]) == (entry["fill"], entry["d"]), (where, name)
        elif mark["kind"] == "line":
            assert mark["stroke"] == entry["fill"], (where, name)
            assert (mark["dash"] or "") == (entry["dash"] or ""), (where, name)
        drawn[name] += 1
    assert all(drawn.values()), f"{where}: runs without marks: {drawn}"


def _assert_bars_named(chart: dict, names: list[str], where: str) -> None:
    """Every run has a bar, and its name is on the axis."""
    bars = {_series(m["label"]) for m in chart["marks"] if m["kind"] == "bar"}
    assert bars >= set(names), f"{where}: runs without a bar: {set(names) - bars}"


PAGES = [
    # (page, address, text it shows when done, charts of runs: index -> how they are told apart)
    ("leaderboard", "", "Per metric", {0: "bars"}),
    ("errors", "errors", "Drill down", {0: "bars", 1: "bars"}),
    ("navigation", "navigation", "NP found the target", {0: "bars", 1: "bars", 2: "bars"}),
    ("grounding", "grounding", "Click points", {0: "bars", 1: "bars"}),
    ("budgets", "budgets", "SR gain over λ = 2", {0: "legend"}),
    ("rescore", "rescore", "rank before", {0: "legend"}),
]


def test_every_chart_names_every_run_and_tells_them_apart(page, many_server, many_out) -> None:
    runs = va.runs(many_out)["run_id"].to_list()
    assert len(runs) == N_RUNS and LONG_RUN_ID in runs and INCOMPLETE_RUN_ID in runs
    browser = AppPage(page, many_server.url, timeout=120)
    for name, path, expect, charts in PAGES:
        browser.open(path, expect)
        browser.screenshot(ARTIFACTS / f"charts-{N_RUNS}-{name}.png", full_page=True)
        assert not browser.errors(), (name, browser.errors())
        drawn = page.evaluate(_CHARTS_JS)
        for index, how in charts.items():
            where = f"{name} chart {index}"
            chart = drawn[index]
            assert chart is not None, f"{where}: not drawn as SVG"
            labels = list(runs)
            if name == "leaderboard":  # the tables' label of a run cut short
                labels[labels.index(INCOMPLETE_RUN_ID)] += INCOMPLETE_MARK
            _assert_names_every_run(chart, labels, where)
            if how == "legend":
                _assert_series_told_apart(chart, labels, where)
            else:
                _assert_bars_named(chart, labels, where)
    assert not browser.page_errors, browser.page_errors
