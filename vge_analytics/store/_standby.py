"""The SQL page's standby query process: a query process (`_isolated`) forked ahead of need,
OUT already open in it, waiting for its one query.

A query process opens OUT afresh (manifest, schemas, datasets: 0.9 to 1.9 s at 100 times the
full benchmark) and reads the footers of the files it scans for the first time; for the SQL
page's first query that was most of its 3.9 s. A server that keeps a standby for OUT
(`keep_standby`: `vge app` when it opens OUT, and each session of the dashboard) has one
forked from the forkserver, capped (`process_memory_cap`) for its whole life as any query
process is, which opens OUT within the page's limits, reads the footers of `episodes` ahead
(`read_footers`, stopping as soon as its query comes) and waits. The rules:

- **Fresh only.** The standby is told the key of OUT's contents (`_kept.contents_key`: the
  manifest's digest, the size and modification time of every table file) as the server's
  store has it when it is forked, and answers nothing if what it opens has another key. A
  query takes it only if the key is the same as the server's at that moment (the server's
  store re-opens after a replay; every file is looked at again), for the same OUT and the
  same limits; otherwise it is ended and the query runs in a new child, as without a standby.
- **One per server, outside the slots.** One for the OUT the server opened last (a dashboard
  has one). While it waits it holds no process slot (`max_queries`): a query takes a slot
  first, as always, then the standby, so the standby never makes a query wait or be refused
  (counted, it would hold a slot no query could have while it waits); at most one more
  process than `max_queries` exists, the one waiting, whose memory is what opening OUT and
  the footers take (within its cap).
- **Used once.** It runs one query, answers and exits; a new standby is forked after each
  query (once the query has answered, so it does not take that query's CPU).
- **No orphans.** A standby that died (killed, out of memory) is replaced and the query runs
  in a new child. `stop_standbys` (also at the server's exit) ends them; a standby whose
  server died without ending it sees its pipe close and exits.
"""

from __future__ import annotations

import atexit
import functools
import threading
from dataclasses import dataclass
from multiprocessing.connection import Connection
from multiprocessing.process import BaseProcess
from pathlib import Path

import replay
from replay.io import EPISODES_TABLE, TABLES

from .._errors import AnalyticsError
from ._contents import table_files
from ._datasets import Deferred
from ._isolated import GRACE, _answer, _start, answer_query
from ._kept import contents_key
from ._limits import SqlLimits, data_segment, memory_headroom, process_memory_cap
from ._store import Store, open_store

FOOTER_TABLES = (EPISODES_TABLE,)
"""The tables whose files' footers a standby reads ahead. At 100 times the full benchmark
those of `episodes` take 0.7 to 0.8 s of CPU and 300 MB, and the first query over it then
costs what a second does (the SQL page's example: 1.2 s of CPU instead of 2.5 s); those of
`steps` take 1.2 s and 470 MB, a few percent of any scan of it (docs/PERFORMANCE.md, SQL)."""

FOOTER_SHARE = 4
"""The footers read ahead take at most this share (1/4) of the memory a query may add to
its process (`memory_headroom`): the rest is the query's, as in a new child."""


@dataclass
class Standby:
    """A standby query process of this server: OUT (resolved), the limits it runs within,
    the key of the contents it was forked for, the process and the parent's end of its pipe."""

    out: str
    limits: SqlLimits
    key: str
    process: BaseProcess
    conn: Connection

    @property
    def pid(self) -> int | None:
        return self.process.pid

    def ask(self, query: str, rows: int) -> tuple[tuple, bytes] | None:
        """Its answer to the query (as `_isolated._answer`: an error it answers is raised), or
        None when it did not take the query: it had died or found OUT changed (then it has
        ended). Waits for it to finish opening OUT, at most the query's time and a grace."""
        try:
            self.conn.send((query, rows))
            wait = None if self.limits.timeout is None else self.limits.timeout + GRACE
            taken = self.conn.poll(wait) and self.conn.recv() == "started"
        except (EOFError, OSError):
            taken = False
        if not taken:
            self.end()
            return None
        return _answer(self.process, self.conn, self.limits, "the query")

    def end(self) -> None:
        """End its process (if it still runs) and close the pipe."""
        self.conn.close()
        if self.process.is_alive():
            self.process.kill()
        self.process.join()


_LOCK = threading.Lock()
_KEPT: dict[str, SqlLimits] = {}
"""The OUTs this server keeps a standby for (resolved), with the limits it runs within."""
_STANDBY: dict[str, Standby] = {}
"""The standby of each of them, while one waits."""
_FILES: list = [None, None]
"""(store, its table files): the files of the server's store, listed once per store."""


def _where(out: str | Path) -> str:
    return str(Path(out).resolve())


def keep_standby(out: str | Path, limits: SqlLimits) -> None:
    """Keep a standby query process for OUT's SQL page queries within `limits` from now on
    (the dashboard, when it opens OUT), and none for another OUT; started now if none waits.
    Nothing for an OUT without a key of its contents (in object storage, without a
    manifest)."""
    where = _where(out)
    with _LOCK:
        if _KEPT.get(where) == limits and where in _STANDBY:
            return
        others = [w for w in _KEPT if w != where]
    for other in others:  # a server keeps one: for the OUT it opened last
        stop_standbys(other)
    _stop_at_exit()
    with _LOCK:
        _KEPT[where] = limits
    renew(where)


@functools.cache
def _stop_at_exit() -> None:
    """End the standbys when this process exits (once registered)."""
    atexit.register(stop_standbys)


def current_key(out: str | Path) -> str | None:
    """The key of OUT's contents now, as the server's store sees them (re-opened after a
    replay; each table file looked at again), or None (no store, no key)."""
    try:
        store = open_store(out)
    except AnalyticsError:
        return None
    if store.digest is None or not isinstance(store.out, Path):
        return None
    where = replay.location(store.out)
    files = _FILES[1] if _FILES[0] is store else None
    if files is None:
        files = {table: table_files(where, store.manifest, table) for table in TABLES}
        _FILES[:] = [store, files]
    return contents_key(where, files, store.digest)


def renew(out: str | Path) -> None:
    """Fork a standby for OUT if this server keeps one and none is waiting (or it died)."""
    where = _where(out)
    with _LOCK:
        limits = _KEPT.get(where)
        waiting = _STANDBY.get(where)
        if limits is None or (waiting is not None and waiting.process.is_alive()):
            return
        _STANDBY.pop(where, None)
    if waiting is not None:
        waiting.end()
    key = current_key(where)
    if key is None:
        return
    process, conn = _start(_standby_child, (where, key, limits, FOOTER_TABLES), duplex=True)
    standby = Standby(where, limits, key, process, conn)
    with _LOCK:
        if _KEPT.get(where) == limits and where not in _STANDBY:
            _STANDBY[where] = standby
            return
    standby.end()  # another thread started one meanwhile, or OUT is no longer kept


def take(out: str | Path, limits: SqlLimits) -> Standby | None:
    """The standby of OUT for a query within `limits`, taken (no other query gets it), if it
    is alive and fresh: its key is OUT's now (`current_key`). A dead or stale one is ended."""
    where = _where(out)
    with _LOCK:
        standby = _STANDBY.get(where)
        if standby is None or standby.limits != limits:
            return None
        del _STANDBY[where]
    if standby.process.is_alive() and current_key(where) == standby.key:
        return standby
    standby.end()
    return None


def stop_standbys(out: str | Path | None = None) -> None:
    """End the standby of OUT (None: of every OUT) and keep none for it from now on."""
    with _LOCK:
        wheres = list(_KEPT) if out is None else [_where(out)]
        ended = [_STANDBY.pop(w) for w in wheres if w in _STANDBY]
        for where in wheres:
            _KEPT.pop(where, None)
    for standby in ended:
        standby.end()


def standby_pid(out: str | Path) -> int | None:
    """The process id of OUT's standby while one waits (None: none)."""
    with _LOCK:
        standby = _STANDBY.get(_where(out))
    return None if standby is None else standby.pid


def _standby_child(
    conn: Connection, out: str, key: str, limits: SqlLimits, footers: tuple[str, ...] = ()
) -> None:
    """The standby's process: open OUT within `limits` (capped for its life), read the
    footers of the tables `footers` ahead, wait for its one query and answer it. It exits
    without a word when OUT cannot be opened or is not what `key` says (the query then runs
    in a new child, which reports what is wrong), or when the server closes the pipe."""
    with conn, process_memory_cap(limits):
        try:
            store = open_store(out, limits)
        except (AnalyticsError, MemoryError):
            return
        if store.contents != key:
            return
        read_footers(store, footers, conn, limits)
        try:
            query, rows = conn.recv()
        except (EOFError, OSError):
            return  # the server ended it, or ended
        conn.send("started")
        answer_query(conn, out, query, rows, limits)


def read_footers(
    store: Store, tables: tuple[str, ...], conn: Connection, limits: SqlLimits
) -> None:
    """Read the footers of the files of `tables` now, as a first scan would (each file of a
    dataset keeps its footer once read: a query then plans without opening it), until the
    query comes or they have taken `1 / FOOTER_SHARE` of the query's memory. Only a head
    start: a failure leaves the rest to the query."""
    budget = data_segment() + memory_headroom(limits) // FOOTER_SHARE
    for table in tables:
        source = store.sources.get(table)
        try:
            if isinstance(source, Deferred):
                source = source.source()
            for n, fragment in enumerate(getattr(source, "get_fragments", list)()):
                if conn.poll() or (n % 64 == 0 and data_segment() > budget):
                    return
                fragment.ensure_complete_metadata()
        except (OSError, MemoryError, ValueError):  # pyarrow's errors are OSError, ValueError
            return


__all__ = [
    "FOOTER_SHARE",
    "FOOTER_TABLES",
    "Standby",
    "keep_standby",
    "read_footers",
    "renew",
    "standby_pid",
    "stop_standbys",
    "take",
]
