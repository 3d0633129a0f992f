"""The dashboard as a person sees it: `vge app` as a real server, pages in Playwright's Chromium.

- `AppServer`: `vge app OUT --headless --port <free port> [options]` (or `vge play BENCH`)
  as a real process (its own session, optionally under an address-space bound so a
  regression cannot eat the machine), waited for until it answers, stopped with its peak
  memory measured.
- `served`: an `AppServer` whose log, once it stopped, holds no traceback.
- `AppPage`: a Playwright page on that server with the waits a Streamlit app needs: a page
  is *rendered* when the app's end-of-run marker of a run after the one before is there
  (`app._lifecycle.END_MARKER`), nothing is stale, every visible chart has drawn, every image has
  loaded, every visible table has its cells, no skeleton or status widget is left, and the
  page shows the expected text, steadily for a moment.

Used by the browser tests (`tests/app/conftest.py` makes fixtures of them) and by
`benchmarks/bench_app.py`. Chromium is Debian's (`/usr/bin/chromium`), launched through
Playwright's `executable_path`: nothing is downloaded.
"""

from __future__ import annotations

import contextlib
import os
import resource
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from collections.abc import Iterator, Sequence
from pathlib import Path

from playwright.sync_api import Page

CHROMIUM = "/usr/bin/chromium"
LAUNCH_ARGS: dict = {
    "executable_path": CHROMIUM,
    "args": ["--disable-gpu", "--disable-dev-shm-usage", "--hide-scrollbars", "--mute-audio"],
}
"""`browser_type.launch(**LAUNCH_ARGS)`: Debian's Chromium, headless."""

_DONE_JS = """(after) => {
  const shown = e => e.offsetParent !== null && !e.closest('details:not([open])');
  if (document.querySelector('[data-testid="stException"]')) return true;  // failed: stop
  const marker = document.getElementById('vge-page-done');
  if (!marker || Number(marker.dataset.run || 0) <= after) return false;
  if (document.querySelector('[data-stale="true"]')) return false;
  if (document.querySelector('[data-testid="stSkeleton"], [data-testid="stStatusWidget"]'))
    return false;
  for (const c of document.querySelectorAll('[data-testid="stVegaLiteChart"]'))
    if (shown(c) && !c.querySelector('canvas, svg')) return false;
  for (const i of document.querySelectorAll('img'))
    if (!i.complete) return false;
  for (const d of document.querySelectorAll('[data-testid="stDataFrame"]'))
    if (shown(d) && !d.querySelector('[data-testid^="glide-cell-"]')) return false;
  return true;
}"""
_RUN_JS = (
    "() => Number((document.getElementById('vge-page-done') || {dataset: {}}).dataset.run || 0)"
)
# Every table's cells as rows of text: [[header...], [row 1...], ...] per st.dataframe
# (from the grid's accessible table: `thead th`, and cells `glide-cell-<col>-<row>`).
_TABLES_JS = """() => Array.from(document.querySelectorAll('[data-testid="stDataFrame"]')).map(d => {
  const header = Array.from(d.querySelectorAll('thead th')).map(h => h.textContent);
  const rows = [];
  for (const c of d.querySelectorAll('[data-testid^="glide-cell-"]')) {
    const [col, row] = c.getAttribute('data-testid').split('-').slice(2).map(Number);
    (rows[row] = rows[row] || [])[col] = c.textContent;
  }
  return [header, ...rows.filter(r => r)];
})"""
# The message of each exception and error box (an error box's text without its icon).
_ERRORS_JS = """() => Array.from(document.querySelectorAll(
  '[data-testid="stException"], [data-testid="stAlertContentError"]')).map(e =>
    (e.querySelector('[data-testid="stMarkdownContainer"]') || e).innerText.trim())"""


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def answering(url: str, proc: subprocess.Popen, startup: float) -> bool:
    """Wait until the Streamlit server at `url` answers its health check (True), or `proc`
    ended or `startup` seconds went by first (False)."""
    deadline = time.monotonic() + startup
    while True:
        try:
            with urllib.request.urlopen(f"{url}/_stcore/health", timeout=2) as r:
                if r.status == 200:
                    return True
        except OSError:
            pass
        if proc.poll() is not None or time.monotonic() > deadline:
            return False
        time.sleep(0.2)


class AppServer:
    """`vge app OUT` (or `vge COMMAND OUT`: `play BENCH`) on a free port; a context manager
    (start, then stop)."""

    def __init__(
        self,
        out: Path,
        *,
        options: Sequence[str] = (),
        log: Path,
        address_space: int | None = None,
        startup: float = 60.0,
        command: str = "app",
    ) -> None:
        self.out = out
        self.command = command
        self.port = free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        self.log = log
        self.options = list(options)
        self.address_space = address_space
        """Bytes of address space the server (and every process it starts) may map."""
        self.startup = startup
        self.peak_memory: int | None = None
        """Peak resident memory of the server process (bytes), known after `stop`."""
        self._proc: subprocess.Popen | None = None

    @property
    def pid(self) -> int:
        assert self._proc is not None
        return self._proc.pid

    def _limit(self) -> None:  # runs in the child, before exec
        if self.address_space is not None:
            limit = (self.address_space, self.address_space)
            resource.setrlimit(resource.RLIMIT_AS, limit)

    def start(self) -> AppServer:
        cmd = [sys.executable, "-m", "vge_analytics.cli", self.command, str(self.out)]
        cmd += ["--port", str(self.port), "--headless", *self.options]
        env = {**os.environ, "PYTHONUNBUFFERED": "1"}
        env.pop("VGE_APP_OUT", None)
        self.log.parent.mkdir(parents=True, exist_ok=True)
        with self.log.open("wb") as sink:
            self._proc = subprocess.Popen(
                cmd,
                stdout=sink,
                stderr=subprocess.STDOUT,
                env=env,
                start_new_session=True,
                preexec_fn=self._limit,
            )
        if not answering(self.url, self._proc, self.startup):
            self.stop()
            raise RuntimeError(f"vge {self.command} did not start:\n{self.log.read_text()}")
        return self

    def stop(self) -> None:
        """SIGTERM to the server's process group (SIGKILL after 10 s); records its peak
        resident memory from the kernel's accounting (`wait4`)."""
        proc, self._proc = self._proc, None
        if proc is None or proc.returncode is not None:
            return
        os.killpg(proc.pid, signal.SIGTERM)
        deadline = time.monotonic() + 10
        while True:
            pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                break
            if time.monotonic() > deadline:
                os.killpg(proc.pid, signal.SIGKILL)
                pid, status, usage = os.wait4(proc.pid, 0)
                break
            time.sleep(0.05)
        proc.returncode = os.waitstatus_to_exitcode(status)
        self.peak_memory = usage.ru_maxrss * 1024

    def kill(self) -> None:
        """SIGKILL to the server's process group: the server dies as in a crash, with no
        chance to clean up."""
        proc, self._proc = self._proc, None
        if proc is None or proc.returncode is not None:
            return
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()

    def text(self) -> str:
        return self.log.read_text(errors="replace")

    def __enter__(self) -> AppServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


@contextlib.contextmanager
def served(*args: object, **kwargs: object) -> Iterator[AppServer]:
    """An `AppServer` (same arguments) for the block; once it has stopped, its log must hold
    no traceback: an exception the page caught and showed is still a bug of the server's."""
    with AppServer(*args, **kwargs) as server:  # type: ignore[arg-type]
        yield server
    assert "Traceback" not in server.text(), server.text()


class AppPage:
    """A Playwright page on a running dashboard, with Streamlit-aware waits."""

    def __init__(self, page: Page, base_url: str, *, timeout: float = 40.0) -> None:
        self.page = page
        self.base = base_url.rstrip("/")
        self.timeout = timeout
        self.page_errors: list[str] = []
        """JavaScript errors the page raised (Playwright's `pageerror` events)."""
        page.on("pageerror", lambda exc: self.page_errors.append(str(exc)))

    # ---------------------------------------------------------------- waiting
    def run_number(self) -> int:
        """The number of the session's last finished script run (0 before the first)."""
        return int(self.page.evaluate(_RUN_JS) or 0)

    def wait_rendered(
        self, expect: str, started: float, *, after: int = 0, settle: float = 0.3
    ) -> float:
        """Wait until a run after `after` has rendered and the page shows `expect`, steadily
        for `settle` seconds; returns the seconds from `started` to the first such moment."""
        deadline = started + self.timeout
        idle_since: float | None = None
        while True:
            now = time.monotonic()
            done = bool(self.page.evaluate(_DONE_JS, after))
            if done and expect in self.text():
                idle_since = idle_since or now
                if now - idle_since >= settle:
                    return idle_since - started
            else:
                idle_since = None
            if now > deadline:
                raise TimeoutError(
                    f"page did not show {expect!r} within {self.timeout:.0f}s; it shows:\n"
                    + self.text()[:2000]
                )
            time.sleep(0.05)

    # ---------------------------------------------------------------- moving around
    def open(self, path: str, expect: str, *, settle: float = 0.3) -> float:
        """Load `base/path` (a new session) and wait until it has rendered and shows
        `expect`; returns the seconds from navigation to the first rendered moment."""
        started = time.monotonic()
        self.page.goto(f"{self.base}/{path.lstrip('/')}")
        return self.wait_rendered(expect, started, settle=settle)

    def navigate(self, path: str, expect: str, *, settle: float = 0.3) -> float:
        """Go to another page by its link in the sidebar, as a person does (the same
        session, no reload), and wait as `open` does."""
        before = self.run_number()
        link = self.page.locator(f'[data-testid="stSidebarNav"] a[href$="{path}"]').first
        started = time.monotonic()
        link.click()
        return self.wait_rendered(expect, started, after=before, settle=settle)

    def follow_link(self, text: str, expect: str, *, settle: float = 0.3) -> str:
        """Click the first link whose text contains `text` and wait for the page it opens;
        returns the new address."""
        before = self.run_number()
        link = self.page.locator("a", has_text=text).first
        link.wait_for(timeout=self.timeout * 1000)
        started = time.monotonic()
        link.click()
        self.wait_rendered(expect, started, after=before, settle=settle)
        return self.page.url

    def run_query(self, query: str, expect: str, *, label: str = "Query") -> float:
        """Type `query` into the text area labelled `label`, run it with Ctrl+Enter (the
        same session), and wait until the rerun has rendered and shows `expect`."""
        before = self.run_number()
        box = self.page.get_by_label(label)
        box.fill(query)
        started = time.monotonic()
        box.press("Control+Enter")
        return self.wait_rendered(expect, started, after=before)

    # ---------------------------------------------------------------- reading
    def text(self) -> str:
        return str(self.page.evaluate("() => document.body ? document.body.innerText : ''"))

    def tables(self) -> list[list[list[str]]]:
        """The cells of every table on the page (header row first; rows the grid has drawn)."""
        return list(self.page.evaluate(_TABLES_JS) or [])

    def table_with(
        self, header: list[str], *, index: int = -1, settle: float = 0.3
    ) -> list[list[str]]:
        """The cells of table `index` once its header starts with `header` and its cells
        have stayed the same for `settle` seconds: a table that replaces another in the same
        place (the SQL page's result) may still show the old one's cells for a moment after
        the rerun's text has rendered, on a loaded machine."""
        deadline = time.monotonic() + self.timeout
        seen: list[list[str]] | None = None
        since = 0.0
        while True:
            now = time.monotonic()
            tables = self.tables()
            table = tables[index] if tables else None
            if table and table[0][: len(header)] == header and len(table) > 1:
                if table != seen:
                    seen, since = table, now
                elif now - since >= settle:
                    return table
            else:
                seen = None
            if now > deadline:
                raise TimeoutError(f"no steady table with header {header}: {tables}")
            time.sleep(0.05)

    def errors(self) -> list[str]:
        """Texts of the exceptions and error boxes the page shows."""
        return list(self.page.evaluate(_ERRORS_JS) or [])

    # ---------------------------------------------------------------- acting
    def select_first_row(self, table: int = -1) -> None:
        """Tick the selection box of the first row of a selectable table (-1: the last one
        on the page): the grid is a canvas, so this clicks where the box is drawn."""
        grid = self.page.locator('[data-testid="stDataFrame"]').nth(table)
        grid.scroll_into_view_if_needed()
        box = grid.bounding_box()
        assert box is not None, "the table is not visible"
        self.page.mouse.click(box["x"] + 15, box["y"] + 35 + 17)

    def download(self, button_text: str, folder: Path) -> Path:
        """Click the button whose text contains `button_text`; returns the file it
        downloaded, saved into `folder` under its suggested name."""
        folder.mkdir(parents=True, exist_ok=True)
        with self.page.expect_download(timeout=self.timeout * 1000) as info:
            self.page.locator("button", has_text=button_text).first.click()
        download = info.value
        target = folder / download.suggested_filename
        download.save_as(target)
        return target

    def screenshot(self, path: Path, *, full_page: bool = False) -> Path:
        path.parent.mkdir(parents=True, exist_ok=True)
        self.page.screenshot(path=str(path), full_page=full_page)
        return path

    def set_height(self, height: int) -> None:
        size = self.page.viewport_size or {"width": 1400}
        self.page.set_viewport_size({"width": size["width"], "height": height})
