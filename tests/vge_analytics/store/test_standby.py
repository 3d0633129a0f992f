"""The SQL page's standby query process (`store._standby`), with real processes: the first
query runs in it, a stale or dead one is not used (the query runs in a new child, as without
one), its limits are a query process's, and nothing is left running once it is stopped or
its server ends. Every check counts processes or reads their ids; none times them."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from multiprocessing import forkserver
from pathlib import Path

import pytest

import vge_analytics as va
from tests.vge_analytics.store.kept import copy_out
from vge_analytics.store import _isolated, _standby
from vge_analytics.store._limits import SqlLimits

LIMITS = SqlLimits.make(memory="256MB", timeout=20)
QUERY = "SELECT run_id, count(*) AS n FROM steps GROUP BY run_id ORDER BY run_id"
ENDLESS = "with recursive r(n) as (select 1 union all select n + 1 from r) select count(*) from r"
GROWS = "with recursive r(s) as (select 'x' union all select s || s from r) select count(*) from r"
PATIENCE = 120.0
"""Seconds a test waits for a process to start or end, on a busy machine (never near the
time it takes: it polls)."""


def running(pid: int | None) -> bool:
    """Whether process `pid` exists and has not ended (a zombie has ended)."""
    if pid is None:
        return False
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def children(parent: int) -> list[int]:
    """The running processes whose parent is `parent`."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == parent and fields[0] != "Z":
            found.append(int(entry.name))
    return found


def query_processes() -> list[int]:
    """The query processes of this test process: the forkserver's children."""
    pid = forkserver._forkserver._forkserver_pid
    return [] if pid is None else children(pid)


def until(condition, what: str) -> None:
    deadline = time.monotonic() + PATIENCE
    while not condition():
        assert time.monotonic() < deadline, what
        time.sleep(0.05)


@pytest.fixture
def kept(hand_out):
    """A standby kept for the hand-worked OUT; stopped after the test."""
    _standby.keep_standby(hand_out, LIMITS)
    yield hand_out
    _standby.stop_standbys()
    until(lambda: not query_processes(), "query processes left after stop_standbys")


def test_the_first_query_runs_in_the_standby(kept):
    first = _standby.standby_pid(kept)
    assert running(first)
    result = _isolated.run_isolated(kept, QUERY, 100, LIMITS)
    assert result.standby and result.pid == first
    assert result.frame.equals(va.sql(kept, QUERY))
    until(lambda: not running(first), "the standby did not exit after its query")
    # A new one waits for the next query, and only it runs.
    second = _standby.standby_pid(kept)
    assert running(second) and second != first
    assert query_processes() == [second]
    again = _isolated.run_isolated(kept, "SELECT 42 AS answer", 10, LIMITS)
    assert again.standby and again.pid == second
    assert again.frame.to_dicts() == [{"answer": 42}]


def test_each_query_runs_in_the_standby_in_turn(kept):
    pids = []
    for n in range(3):
        result = _isolated.run_isolated(kept, f"SELECT {n} AS n", 10, LIMITS)
        assert result.standby and result.frame.to_dicts() == [{"n": n}]
        pids.append(result.pid)
    assert len(set(pids)) == 3
    until(lambda: len(query_processes()) == 1, "more than one standby left waiting")


def _fresh_only(out: Path, change) -> None:
    """`change(out)` after a standby was forked: the next query runs in a new child, the
    stale standby has ended, and the one forked after has OUT's new contents."""
    _standby.keep_standby(out, LIMITS)
    stale = _standby.standby_pid(out)
    key = _standby.current_key(out)
    change(out)
    assert _standby.current_key(out) != key
    result = _isolated.run_isolated(out, QUERY, 100, LIMITS)
    assert not result.standby and result.pid != stale
    assert result.frame.equals(va.sql(out, QUERY))
    assert not running(stale)
    renewed = _standby.standby_pid(out)
    assert running(renewed) and renewed != stale
    assert _standby._STANDBY[str(out.resolve())].key == _standby.current_key(out)
    assert _isolated.run_isolated(out, QUERY, 100, LIMITS).standby


def _touch_a_table_file(out: Path) -> None:
    path = sorted((out / "steps").rglob("*.parquet"))[0]
    st = path.stat()
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))


def _rewrite_the_manifest(out: Path) -> None:  # as a replay does: a new file, renamed
    manifest = out / "manifest.json"
    data = json.loads(manifest.read_text())
    data["totals"] = {**data.get("totals", {}), "note": "replayed again"}
    (out / "manifest.json.new").write_text(json.dumps(data))
    os.replace(out / "manifest.json.new", manifest)


@pytest.mark.parametrize("change", [_touch_a_table_file, _rewrite_the_manifest])
def test_a_stale_standby_is_not_used(hand_out, tmp_path, change):
    out = copy_out(hand_out, tmp_path / "out")
    try:
        _fresh_only(out, change)
    finally:
        _standby.stop_standbys()
    until(lambda: not query_processes(), "query processes left after stop_standbys")


def test_a_standby_that_finds_other_contents_answers_nothing(hand_out):
    """OUT changed between the server's look and the standby's open: it ends unasked."""
    where = str(hand_out.resolve())
    process, conn = _isolated._start(_standby._standby_child, (where, "0" * 16, LIMITS), duplex=True)
    standby = _standby.Standby(where, LIMITS, "0" * 16, process, conn)
    assert standby.ask("SELECT 1", 10) is None
    assert not process.is_alive()


def test_a_standby_for_another_out_is_never_used(hand_out, pair_out):
    try:
        _standby.keep_standby(pair_out, LIMITS)
        other = _standby.standby_pid(pair_out)
        result = _isolated.run_isolated(hand_out, QUERY, 100, LIMITS)
        assert not result.standby and result.frame.equals(va.sql(hand_out, QUERY))
        assert _standby.standby_pid(pair_out) == other  # still waiting for its own OUT
        assert _standby.standby_pid(hand_out) is None  # none kept for this one
        # Nor one of other limits.
        other_limits = SqlLimits.make(memory="512MB", timeout=20)
        assert not _isolated.run_isolated(pair_out, QUERY, 100, other_limits).standby
        # A server keeps one: for the OUT it opened last.
        _standby.keep_standby(hand_out, LIMITS)
        until(lambda: not running(other), "the other OUT's standby still runs")
        assert query_processes() == [_standby.standby_pid(hand_out)]
    finally:
        _standby.stop_standbys()
    until(lambda: not query_processes(), "query processes left after stop_standbys")


def test_a_dead_standby_is_replaced(kept):
    dead = _standby.standby_pid(kept)
    os.kill(dead, signal.SIGKILL)
    until(lambda: not running(dead), "the killed standby still runs")
    result = _isolated.run_isolated(kept, QUERY, 100, LIMITS)
    assert not result.standby and result.pid != dead
    assert result.frame.equals(va.sql(kept, QUERY))
    assert running(_standby.standby_pid(kept))
    assert _isolated.run_isolated(kept, QUERY, 100, LIMITS).standby


@pytest.mark.parametrize(
    ("query", "limit", "message"),
    [
        (ENDLESS, "time", "the query ran past its time limit of 2 s and was stopped"),
        (
            GROWS,
            "memory",
            "the query needed more memory than its limit (256 MB in memory, 512 MB on disk) "
            "and was stopped",
        ),
    ],
)
def test_limits_apply_in_the_standby(hand_out, monkeypatch, query, limit, message):
    """The same one-line error as a new child's (asked first), from the standby (asked)."""
    limits = SqlLimits.make(memory="256MB", timeout=2)
    with pytest.raises(va.QueryLimitError) as fresh:
        _isolated.run_isolated(hand_out, query, 10, limits)
    asked = []
    ask = _standby.Standby.ask

    def spy(self, *args):
        asked.append(self.pid)
        return ask(self, *args)

    monkeypatch.setattr(_standby.Standby, "ask", spy)
    try:
        _standby.keep_standby(hand_out, limits)
        first = _standby.standby_pid(hand_out)
        with pytest.raises(va.QueryLimitError) as standby:
            _isolated.run_isolated(hand_out, query, 10, limits)
        assert asked == [first]
        assert str(standby.value) == str(fresh.value) == message
        assert standby.value.limit == fresh.value.limit == limit
        assert not running(first)
        assert _isolated.run_isolated(hand_out, "SELECT 1 AS one", 10, limits).standby
    finally:
        _standby.stop_standbys()
    until(lambda: not query_processes(), "query processes left after stop_standbys")


SERVER = """
import os, sys, time
from vge_analytics.store import _isolated, _standby
from vge_analytics.store._limits import SqlLimits

if __name__ == "__main__":
    limits = SqlLimits.make(memory="256MB", timeout=20)
    _standby.keep_standby(sys.argv[1], limits)
    used = _isolated.run_isolated(sys.argv[1], "SELECT 1 AS one", 10, limits)
    from multiprocessing import forkserver
    pids = [used.pid, _standby.standby_pid(sys.argv[1]), forkserver._forkserver._forkserver_pid]
    print(" ".join(map(str, pids)), flush=True)
    if sys.argv[2] == "wait":
        time.sleep(600)
    sys.stdin.readline()  # exits when the test has looked at its processes
"""


@pytest.mark.parametrize("end", ["exit", "killed"])
def test_nothing_runs_after_the_server_ends(hand_out, tmp_path, end):
    """A server that exits ends its standby (and the forkserver); one killed outright leaves
    a standby that sees its pipe close and exits."""
    script = tmp_path / "server.py"  # a file: the forkserver's children import it by path
    script.write_text(SERVER)
    server = subprocess.Popen(
        [sys.executable, str(script), str(hand_out), "wait" if end == "killed" else "exit"],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        used, waiting, forks = map(int, server.stdout.readline().split())
        assert running(waiting) and waiting != used
        if end == "killed":
            server.send_signal(signal.SIGKILL)
        else:  # (not before: a server that exited at once raced the look at its standby)
            server.stdin.close()
        assert server.wait(timeout=PATIENCE) == (-signal.SIGKILL if end == "killed" else 0)
    finally:
        server.kill()
        server.wait()
    until(
        lambda: not any(running(p) for p in (used, waiting, forks)),
        "a query process or the forkserver still runs after its server ended",
    )


class _Fragment:
    def __init__(self, read: list) -> None:
        self.read = read

    def ensure_complete_metadata(self) -> None:
        self.read.append(1)


class _Files:
    def __init__(self, n: int, read: list) -> None:
        self.fragments = [_Fragment(read) for _ in range(n)]

    def get_fragments(self) -> list[_Fragment]:
        return self.fragments


class _Pipe:
    def __init__(self, query_after: int, read: list) -> None:
        self.query_after, self.read = query_after, read

    def poll(self) -> bool:
        return len(self.read) >= self.query_after


@pytest.mark.parametrize(
    ("query_after", "grows", "read"),
    [(10**6, 0, 200), (70, 0, 70), (10**6, 1, 64)],
    ids=["all", "until-the-query-comes", "until-the-budget"],
)
def test_footers_are_read_until_the_query_or_the_budget(monkeypatch, query_after, grows, read):
    """200 files: all footers read; stopped when the query comes (after 70); stopped at the
    first look past the budget (every 64 files), each file here taking a quarter of it."""
    done: list = []
    store = va.store.memory_store({}, label=Path("x"))
    store.sources = {"episodes": _Files(200, done)}
    start = 10**9
    quarter = _standby.memory_headroom(LIMITS) // _standby.FOOTER_SHARE
    monkeypatch.setattr(_standby, "data_segment", lambda: start + grows * len(done) * quarter)
    _standby.read_footers(store, ("episodes", "steps"), _Pipe(query_after, done), LIMITS)
    assert len(done) == read
    store.close()
