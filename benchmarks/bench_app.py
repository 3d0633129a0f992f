"""Render time of every dashboard page, as a browser sees it.

    python benchmarks/bench_app.py OUT [--repeat 3] [--sweep] [--pages Leaderboard,Errors] [--cold-disk]

Starts `vge app OUT --headless` on a free localhost port and loads each page in headless
Chromium through Playwright (the helpers of the browser tests, `tests/app/streamlit_browser.py`),
timing from navigation until the page is rendered (the app's end-of-run marker of that run is
there, nothing is stale, every chart has drawn, every table has its cells, every image has
loaded):

- *first visit*: a fresh page load (new Streamlit session, frontend start included) right
  after the server started, which fills the caches (`st.cache_data`);
- *reload*: the same, later (caches warm), median of `--repeat`;
- *switch*: clicking the page's link in the sidebar from another page, as a person moves
  around the app (same session, no reload), median of `--repeat` rounds through all pages.

Results go to stdout as a markdown table (docs/PERFORMANCE.md, section "Dashboard").

`--screenshots DIR` also saves small screenshots of six pages there (`app-<page>.png`, the
ones docs/APP.md shows), the episode viewer opened at the first component-selection error of
the most successful model run, the Side by side page on the reference run and that model at
the first difference of the first episode only one of them solved whose picture there shows
the planner's optimal box.

Besides the pages as they open, the Side by side page is timed on the heaviest pair it can
be asked for: the two model runs with the most episodes (their diff over every common
episode is computed on the first visit).

`--pages` times only the pages named (titles as in the table, comma-separated; the switch
is then from one of them to the next, and the heavy Side by side pair only with Side by
side among them).

`--cold-disk` first removes the results the dashboard keeps beside OUT
(`OUT/.metric-cache/result-*.arrow`, docs/METRICS.md), so that the first visits compute them
(the very first server on an OUT); without it, a server after another one on the same OUT
reads them (docs/PERFORMANCE.md, *First visits at 100x*).

`--sweep` also times the lambda sweep of every run (computed once and kept on disk; without
it the Budgets page of a large OUT shows a button instead of computing it on a page load).
Run it from the directory `vge replay` ran in (the manifest's relative input paths).
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path

from playwright.sync_api import sync_playwright

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.app.streamlit_browser import LAUNCH_ARGS, AppPage, AppServer  # noqa: E402

PAGES: tuple[tuple[str, str, str], ...] = (
    ("Leaderboard", "", "Per metric"),
    ("Errors", "errors", "Drill down"),
    ("Navigation", "navigation", "NP found the target"),
    ("Grounding", "grounding", "Click points"),
    ("Budgets", "budgets", "Budgets"),
    ("Human vs VLM", "human_vs_vlm", "common episodes"),
    ("Side by side", "side_by_side", "Run B"),
    ("Episode viewer", "episode_viewer", "Download episode as MCAP"),
    ("SQL", "sql", "rows"),
)


SHOTS: tuple[tuple[str, str, str], ...] = (
    ("leaderboard", "", "Per metric"),
    ("errors", "errors", "Drill down"),
    ("grounding", "grounding", "Click points"),
    ("human-vs-vlm", "human_vs_vlm", "common episodes"),
)


def _trim(png: Path, width: int = 900) -> None:
    """Crop the empty bottom of a screenshot (judged right of the sidebar), scale it to
    `width` pixels and store it with a 256-colour palette (small files for the docs)."""
    from PIL import Image, ImageChops

    img = Image.open(png).convert("RGB")
    main = img.crop((img.width // 4, 0, img.width, img.height))
    background = Image.new("RGB", main.size, main.getpixel((main.width - 1, main.height - 1)))
    box = ImageChops.difference(main, background).getbbox()
    if box is not None:
        img = img.crop((0, 0, img.width, min(img.height, box[3] + 24)))
    img = img.resize((width, round(img.height * width / img.width)), Image.Resampling.LANCZOS)
    img.quantize(colors=256, dither=Image.Dither.NONE).save(png, optimize=True)


def side_by_side_shot(out: Path) -> str:
    """The Side by side address of the screenshot: the reference run and the best model at
    the first difference of the first episode one of them solved (of the first 50) whose
    reference picture there has the optimal action's box."""
    import polars as pl

    import vge_analytics as va
    from vge_analytics import dashboard as dash

    references, models = dash.run_choices(va.runs(out))
    a, b = references[0], next(m for m in models if m != references[0])
    rows = dash.pair_rows(out, a, b).filter(
        pl.col("success_a") != pl.col("success_b"),
        pl.col("first_difference") < pl.min_horizontal("steps_a", "steps_b"),
    )
    chosen = rows.row(0, named=True)
    for row in rows.head(50).iter_rows(named=True):
        optimal = dash.side_picture(out, a, row["episode_id"], row["first_difference"]).optimal
        if optimal is not None and optimal.boxes:
            chosen = row
            break
    return (
        f"side_by_side?a={a}&b={b}&episode={chosen['episode_id']}&step={chosen['first_difference']}"
    )


def largest_model_pair(out: Path) -> tuple[str, str] | None:
    """The two non-human runs with the most episodes, or None."""
    import polars as pl

    import vge_analytics as va

    runs = va.runs(out).filter(pl.col("agent_kind") != "human")
    ids = runs.sort(["n_episodes", "run_id"], descending=[True, False])["run_id"].to_list()
    return (ids[0], ids[1]) if len(ids) >= 2 else None


def save_screenshots(browser: AppPage, out: Path, folder: Path) -> None:
    import vge_analytics as va
    from vge_analytics import dashboard as dash

    runs = va.runs(out)
    _, models = dash.run_choices(runs)
    steps, _ = dash.error_step_sample(out, "component_selection", {"run_id": models[:1]}, limit=1)
    row = steps.row(0, named=True)
    viewer = f"episode_viewer?run={row['run_id']}&episode={row['episode_id']}&step={row['step']}"
    shots = [
        *SHOTS,
        ("episode-viewer", viewer, "Download episode as MCAP"),
        ("side-by-side", side_by_side_shot(out), "Run B"),
    ]
    browser.set_height(2400)
    for name, path, expect in shots:
        browser.open(path, expect)
        target = browser.screenshot(folder / f"app-{name}.png")
        _trim(target)
    browser.set_height(1000)


def chosen_pages(titles: str) -> tuple[tuple[str, str, str], ...]:
    """The pages of `PAGES` named in `titles` (comma-separated), in the table's order."""
    wanted = {t.strip() for t in titles.split(",") if t.strip()}
    unknown = wanted - {t for t, _, _ in PAGES}
    if unknown or not wanted:
        known = ", ".join(t for t, _, _ in PAGES)
        raise argparse.ArgumentTypeError(f"unknown page(s) {sorted(unknown)}; pages: {known}")
    return tuple(p for p in PAGES if p[0] in wanted)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--repeat", type=int, default=3, help="warm visits per page")
    parser.add_argument("--sweep", action="store_true", help="also time the lambda sweep")
    parser.add_argument("--screenshots", type=Path, help="save docs screenshots here")
    parser.add_argument("--pages", type=chosen_pages, default=PAGES, help="titles, a,b,...")
    parser.add_argument("--cold-disk", action="store_true", help="forget the kept results")
    args = parser.parse_args()
    pages: tuple[tuple[str, str, str], ...] = args.pages
    if args.cold_disk:
        from replay.io import METRIC_CACHE_DIR

        for kept in (args.out / METRIC_CACHE_DIR).glob("result-*.arrow"):
            kept.unlink()

    import vge_analytics as va
    from vge_analytics import dashboard as dash

    out = dash.check_out(args.out)
    summary = dash.out_summary(out)
    sweep_note = ""
    if args.sweep:
        runs = va.runs(out)["run_id"].to_list()
        started = time.perf_counter()
        dash.computed_sweep(out, runs, [2, 3, 4, 5], workers=2)
        sweep_note = (
            f"lambda sweep 2,3,4,5 of all {len(runs)} runs computed once in "
            f"{time.perf_counter() - started:.1f} s (2 workers), then read from the cache"
        )

    first: dict[str, float] = {}
    reload: dict[str, list[float]] = {t: [] for t, _, _ in pages}
    switch: dict[str, list[float]] = {t: [] for t, _, _ in pages}
    log = Path(tempfile.mkdtemp(prefix="bench-app-")) / "vge-app.log"
    with AppServer(out, log=log) as server, sync_playwright() as playwright:
        chromium = playwright.chromium.launch(**LAUNCH_ARGS)
        page = chromium.new_page(viewport={"width": 1400, "height": 1000})
        browser = AppPage(page, server.url, timeout=300)
        for title, path, expect in pages:
            first[title] = browser.open(path, expect, settle=0.2)
            for _ in range(args.repeat):
                reload[title].append(browser.open(path, expect, settle=0.2))
            print(f"{title}: first visit {first[title]:.2f} s", file=sys.stderr)
        for _ in range(args.repeat):
            for title, path, expect in pages:
                switch[title].append(browser.navigate(f"/{path}", expect, settle=0.2))
        pair = largest_model_pair(out) if any(t == "Side by side" for t, _, _ in pages) else None
        if pair is not None:
            path = f"side_by_side?a={pair[0]}&b={pair[1]}"
            heavy = f"Side by side, {pair[0]} and {pair[1]}"
            first[heavy] = browser.open(path, "Run B", settle=0.2)
            reload[heavy] = [browser.open(path, "Run B", settle=0.2) for _ in range(args.repeat)]
        if args.screenshots is not None:
            save_screenshots(browser, out, args.screenshots)
        chromium.close()

    print(
        f"OUT: {out} ({summary.runs} runs, {summary.episodes:,} episodes, "
        f"{summary.steps:,} steps); {platform.machine()}, {os.cpu_count()} CPUs, "
        f"Python {platform.python_version()}\n"
    )
    print("| page | first visit (s) | reload, median (s) | switch, median (s) | switch, max (s) |")
    print("|---|---:|---:|---:|---:|")
    for title, _, _ in pages:
        print(
            f"| {title} | {first[title]:.2f} | {statistics.median(reload[title]):.2f} "
            f"| {statistics.median(switch[title]):.2f} | {max(switch[title]):.2f} |"
        )
    for title in first.keys() - {t for t, _, _ in pages}:
        print(f"| {title} | {first[title]:.2f} | {statistics.median(reload[title]):.2f} | – | – |")
    if sweep_note:
        print(f"\n{sweep_note}")


if __name__ == "__main__":
    main()
