"""What a page's first visit in a new browser costs before any of the dashboard's work: the
floor Streamlit's frontend sets.

    python benchmarks/bench_frontend_floor.py OUT [--rounds 5]

A person who opens the dashboard in a browser that has never loaded it waits for Streamlit's
frontend to start (its JavaScript fetched, parsed and run, the websocket opened, the first
script run drawn) before any page of ours can show. This times, each in a new headless
Chromium (a fresh profile: nothing cached), from navigation until the page is rendered (the
waits of `tests/app/streamlit_browser.py`):

- *text*: a Streamlit app of a title, a line of text and the end-of-run marker, nothing else;
- *chart*: the same with one small Altair chart (the charts' code is a part of the frontend
  loaded when the first chart is drawn);
- *table*: the same with one small table (`st.dataframe`, three rows; the tables' grid is
  another part loaded when the first table is drawn), as every page of ours has;
- *Leaderboard*: `vge app OUT`'s first page, the server already warm (its queries answered
  once before the rounds, by another browser), so what is timed is the new browser;
- *Leaderboard, same browser*: the same page loaded again in that browser (its cache warm).

The three kinds alternate in each round; the servers run all along. Results go to stdout as
a markdown table (docs/PERFORMANCE.md, section "Dashboard").
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from playwright.sync_api import sync_playwright

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from app._lifecycle import END_MARKER  # noqa: E402
from tests.app.streamlit_browser import (  # noqa: E402
    LAUNCH_ARGS,
    AppPage,
    AppServer,
    answering,
    free_port,
)

TEXT_APP = f"""
import streamlit as st
st.title("Floor")
st.write("A line of text.")
st.markdown('<div id="{END_MARKER}" data-run="1"></div>', unsafe_allow_html=True)
"""
CHART_APP = f"""
import altair as alt
import polars as pl
import streamlit as st
st.title("Floor")
st.write("A line of text.")
data = pl.DataFrame({{"x": [1, 2, 3], "y": [3, 1, 2]}})
st.altair_chart(alt.Chart(data).mark_line().encode(x="x", y="y"), use_container_width=True)
st.markdown('<div id="{END_MARKER}" data-run="1"></div>', unsafe_allow_html=True)
"""
TABLE_APP = f"""
import polars as pl
import streamlit as st
st.title("Floor")
st.write("A line of text.")
st.dataframe(pl.DataFrame({{"x": [1, 2, 3], "y": [3.5, 1.25, 2.0]}}), hide_index=True)
st.markdown('<div id="{END_MARKER}" data-run="1"></div>', unsafe_allow_html=True)
"""


class Floor:
    """`streamlit run` of a one-file app on a free port (a context manager)."""

    def __init__(self, name: str, source: str, folder: Path) -> None:
        self.script = folder / f"floor_{name}.py"
        self.script.write_text(source)
        self.port = free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        self._proc: subprocess.Popen | None = None

    def __enter__(self) -> Floor:
        cmd = [sys.executable, "-m", "streamlit", "run", str(self.script), "--server.headless",
               "true", "--server.port", str(self.port), "--browser.gatherUsageStats", "false"]  # fmt: skip
        self._proc = subprocess.Popen(
            cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=self.script.parent
        )
        if not answering(self.url, self._proc, 60.0):
            self.__exit__()
            raise RuntimeError(f"streamlit did not start for {self.script}")
        return self

    def __exit__(self, *exc: object) -> None:
        if self._proc is not None:
            self._proc.terminate()
            self._proc.wait(timeout=20)


def first_visit(pw, url: str, path: str, expect: str, *, again: bool = False) -> list[float]:
    """Seconds to render `url/path` in a new Chromium (and, with `again`, once more in the
    same browser)."""
    browser = pw.chromium.launch(**LAUNCH_ARGS)
    try:
        page = AppPage(browser.new_page(viewport={"width": 1400, "height": 1000}), url)
        times = [page.open(path, expect)]
        if again:
            times.append(page.open(path, expect))
        return times
    finally:
        browser.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path, help="an OUT for `vge app` (the Leaderboard)")
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args()
    times: dict[str, list[float]] = {}
    with tempfile.TemporaryDirectory() as tmp, sync_playwright() as pw:
        folder = Path(tmp)
        log = folder / "app.log"
        with (
            Floor("text", TEXT_APP, folder) as text,
            Floor("chart", CHART_APP, folder) as chart,
            Floor("table", TABLE_APP, folder) as table,
            AppServer(args.out, log=log) as app,
        ):
            first_visit(pw, app.url, "", "Per metric")  # the server's first visit: its queries
            for round_ in range(args.rounds):
                kinds = [("text", text.url, "A line of text."),
                         ("chart", chart.url, "A line of text."),
                         ("table", table.url, "A line of text."),
                         ("Leaderboard", app.url, "Per metric")]  # fmt: skip
                if round_ % 2:
                    kinds.reverse()
                for name, url, expect in kinds:
                    got = first_visit(pw, url, "", expect, again=name == "Leaderboard")
                    times.setdefault(name, []).append(got[0])
                    if len(got) > 1:
                        times.setdefault("Leaderboard, same browser", []).append(got[1])
    load = " / ".join(f"{x:.1f}" for x in os.getloadavg())
    print(f"## A page's first visit in a new browser: {args.out}\n")
    cpus = os.cpu_count()
    print(
        f"- {args.rounds} rounds, kinds alternating; {cpus} CPUs; load average at the end {load}\n"
    )
    print("| page | median (s) | each round (s) |")
    print("|---|---:|---|")
    for name, got in times.items():
        each = ", ".join(f"{t:.2f}" for t in got)
        print(f"| {name} | {statistics.median(got):.2f} | {each} |")


if __name__ == "__main__":
    main()
