"""A minimal headless-Chromium driver over the DevTools protocol (no selenium, no node).

Debian's `chromium` is started with `--remote-debugging-port=0`; the port it picked is read
from `DevToolsActivePort` in its profile directory, and one page target is driven through a
websocket (`websockets`, a Streamlit dependency): navigate, evaluate JavaScript, screenshot.
Used by the end-to-end test and by `benchmarks/bench_app.py`.
"""

from __future__ import annotations

import base64
import json
import shutil
import subprocess
import tempfile
import time
import urllib.request
from pathlib import Path

from websockets.sync.client import connect

CHROMIUM = "/usr/bin/chromium"
FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-dev-shm-usage",
    "--hide-scrollbars",
    "--mute-audio",
    "--disable-breakpad",
)

# The page is rendered when the app's end-of-run marker of a run after `after` is there
# (`app._ui.END_MARKER`), nothing is stale,
# every visible chart has drawn (a canvas or svg inside), every image has loaded, every
# visible table has its cells (the grid's accessible table), and no skeleton or status widget
# ("Running...") is left; or when the page shows an exception (the caller checks `errors`).
_DONE_JS = """((after) => {
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
})"""
_RUN_JS = "Number((document.getElementById('vge-page-done') || {dataset: {}}).dataset.run || 0)"
_TEXT_JS = "document.body ? document.body.innerText : ''"
# Every table's cells as rows of text: [[header...], [row 1...], ...] per st.dataframe
# (from the grid's accessible table: `thead th`, and cells `glide-cell-<col>-<row>`).
_TABLES_JS = """Array.from(document.querySelectorAll('[data-testid="stDataFrame"]')).map(d => {
  const header = Array.from(d.querySelectorAll('thead th')).map(h => h.textContent);
  const rows = [];
  for (const c of d.querySelectorAll('[data-testid^="glide-cell-"]')) {
    const [col, row] = c.getAttribute('data-testid').split('-').slice(2).map(Number);
    (rows[row] = rows[row] || [])[col] = c.textContent;
  }
  return [header, ...rows.filter(r => r)];
})"""
_ERRORS_JS = (
    'Array.from(document.querySelectorAll(\'[data-testid="stException"], '
    '[data-testid="stAlertContentError"]\')).map(e => e.innerText)'
)


def chromium_path() -> str:
    return CHROMIUM if Path(CHROMIUM).exists() else (shutil.which("chromium") or CHROMIUM)


class Browser:
    """One headless Chromium with one page; use as a context manager."""

    def __init__(self, width: int = 1400, height: int = 1000, timeout: float = 30.0) -> None:
        self.width, self.height, self.timeout = width, height, timeout
        self._profile = tempfile.mkdtemp(prefix="vge-chromium-")
        self._proc: subprocess.Popen | None = None
        self._ws = None
        self._next_id = 0

    # ----------------------------------------------------------------- lifecycle
    def __enter__(self) -> Browser:
        self._proc = subprocess.Popen(
            [
                chromium_path(),
                *FLAGS,
                f"--user-data-dir={self._profile}",
                f"--window-size={self.width},{self.height}",
                "--remote-debugging-port=0",
                "about:blank",
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        port_file = Path(self._profile) / "DevToolsActivePort"
        deadline = time.monotonic() + self.timeout
        while not port_file.exists() or not port_file.read_text().strip():
            if self._proc.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError("chromium did not start (no DevToolsActivePort)")
            time.sleep(0.05)
        port = int(port_file.read_text().split()[0])
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=10) as r:
            targets = json.load(r)
        page = next(t for t in targets if t.get("type") == "page")
        self._ws = connect(
            page["webSocketDebuggerUrl"], max_size=None, open_timeout=10, legacy=True
        )
        self.send("Page.enable")
        self.send("Runtime.enable")
        self.send(
            "Emulation.setDeviceMetricsOverride",
            width=self.width,
            height=self.height,
            deviceScaleFactor=1,
            mobile=False,
        )
        return self

    def __exit__(self, *exc: object) -> None:
        if self._ws is not None:
            self._ws.close()
        if self._proc is not None:
            self._proc.terminate()
            try:
                self._proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self._proc.kill()
                self._proc.wait()
        shutil.rmtree(self._profile, ignore_errors=True)

    # ---------------------------------------------------------------- protocol
    def send(self, method: str, **params: object) -> dict:
        """Send one DevTools command and return its result (events are skipped)."""
        assert self._ws is not None
        self._next_id += 1
        ident = self._next_id
        self._ws.send(json.dumps({"id": ident, "method": method, "params": params}))
        deadline = time.monotonic() + self.timeout
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise TimeoutError(f"no answer to {method}")
            msg = json.loads(self._ws.recv(timeout=remaining))
            if msg.get("id") == ident:
                if "error" in msg:
                    raise RuntimeError(f"{method}: {msg['error']}")
                return msg.get("result", {})

    def evaluate(self, expression: str) -> object:
        result = self.send("Runtime.evaluate", expression=expression, returnByValue=True)
        return result.get("result", {}).get("value")

    # ---------------------------------------------------------------- helpers
    def set_height(self, height: int) -> None:
        self.height = height
        self.send(
            "Emulation.setDeviceMetricsOverride",
            width=self.width,
            height=height,
            deviceScaleFactor=1,
            mobile=False,
        )

    def open(self, url: str, expect: str, *, settle: float = 0.3) -> float:
        """Load `url` and wait until the page has rendered (see `_DONE_JS`), shows `expect`
        and stays so for `settle` seconds; returns the seconds from navigation to the moment
        it was first rendered."""
        started = time.monotonic()
        self.send("Page.navigate", url=url)
        return self.wait_idle(expect, started, settle=settle)

    def navigate(self, path: str, expect: str, *, settle: float = 0.3) -> float:
        """Go to another page of the app the way a person does, by clicking its link in the
        sidebar (no page reload: the same session), and wait as `open` does."""
        before = int(self.evaluate(_RUN_JS) or 0)
        clicked = self.evaluate(
            "(() => { const a = Array.from(document.querySelectorAll('[data-testid=\"stSidebarNav\"] a'))"
            f".find(a => new URL(a.href).pathname === {path!r}); if (a) a.click(); return !!a; }})()"
        )
        if not clicked:
            raise RuntimeError(f"no sidebar link to {path}")
        return self.wait_idle(expect, time.monotonic(), settle=settle, after=before)

    def wait_idle(
        self, expect: str, started: float, *, settle: float = 0.3, after: int = 0
    ) -> float:
        deadline = started + self.timeout
        idle_since: float | None = None
        while True:
            now = time.monotonic()
            text = self.evaluate(_TEXT_JS) or ""
            done = bool(self.evaluate(f"{_DONE_JS}({after})"))
            if expect in text and done:
                idle_since = idle_since or now
                if now - idle_since >= settle:
                    return idle_since - started
            else:
                idle_since = None
            if now > deadline:
                raise TimeoutError(
                    f"page did not show {expect!r} within {self.timeout:.0f}s; it shows:\n"
                    + text[:2000]
                )
            time.sleep(0.05)

    def text(self) -> str:
        return str(self.evaluate(_TEXT_JS) or "")

    def click(self, x: float, y: float) -> None:
        """A left click at page coordinates (CSS pixels of the viewport)."""
        for kind in ("mousePressed", "mouseReleased"):
            self.send("Input.dispatchMouseEvent", type=kind, x=x, y=y, button="left", clickCount=1)

    def select_first_row(self, table: int = -1) -> None:
        """Tick the selection box of the first row of a selectable table (-1: the last one
        on the page): the grid is a canvas, so this clicks where the box is drawn."""
        x, y = self.evaluate(
            "(() => { const ds = document.querySelectorAll('[data-testid=\"stDataFrame\"]');"
            f" const d = ds[({table} + ds.length) % ds.length]; d.scrollIntoView();"
            " const r = d.getBoundingClientRect(); return [r.x + 15, r.y + 35 + 17]; })()"
        )
        self.click(x, y)

    def follow_link(self, text: str, expect: str, *, settle: float = 0.3) -> str:
        """Click the first link whose text contains `text`, wait for the page it opens to
        render (showing `expect`); returns the new address."""
        before = int(self.evaluate(_RUN_JS) or 0)
        deadline = time.monotonic() + self.timeout
        while not self.evaluate(
            f"Array.from(document.querySelectorAll('a')).some(a => a.innerText.includes({text!r}))"
        ):
            if time.monotonic() > deadline:
                raise TimeoutError(f"no link with {text!r}")
            time.sleep(0.05)
        self.evaluate(
            "Array.from(document.querySelectorAll('a'))"
            f".find(a => a.innerText.includes({text!r})).click()"
        )
        self.wait_idle(expect, time.monotonic(), settle=settle, after=before)
        return str(self.evaluate("location.href"))

    def download(self, button_text: str, folder: Path) -> Path:
        """Click the button whose text contains `button_text` and wait for the file it
        downloads into `folder`; returns its path."""
        folder.mkdir(parents=True, exist_ok=True)
        self.send("Browser.setDownloadBehavior", behavior="allow", downloadPath=str(folder))
        before = set(folder.iterdir())
        self.evaluate(
            "Array.from(document.querySelectorAll('button'))"
            f".find(b => b.innerText.includes({button_text!r})).click()"
        )
        deadline = time.monotonic() + self.timeout
        while True:
            new = [
                p
                for p in folder.iterdir()
                if p not in before and not p.name.endswith(".crdownload")
            ]
            if new:
                return new[0]
            if time.monotonic() > deadline:
                raise TimeoutError(f"nothing downloaded after clicking {button_text!r}")
            time.sleep(0.1)

    def tables(self) -> list[list[list[str]]]:
        """The cells of every table on the page (header row first; rows the grid has drawn)."""
        return list(self.evaluate(_TABLES_JS) or [])

    def errors(self) -> list[str]:
        return list(self.evaluate(_ERRORS_JS) or [])

    def screenshot(self, path: Path) -> Path:
        data = self.send("Page.captureScreenshot", format="png")["data"]
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(base64.b64decode(data))
        return path
