"""The writer lock of an OUT in object storage: a lease, the object `OUT/.replay/lock`.

An object store has neither `flock` nor an atomic create-if-absent through pyarrow's
filesystems, so a second `vge replay` into the same prefix is kept out by a lease instead:

- taking it: refused in one line while another writer's lease is fresh (renewed less than
  `LEASE_SECONDS` ago, by the store's clock on the object); else our token is written and
  read back (a writer that wrote after us holds it);
- holding it: renewed every `RENEW_SECONDS` by a thread, and checked before each commit
  (each run's, and the last `publish`): a writer whose token was overwritten stops before
  it changes anything more, with one line;
- releasing it: the object is deleted (if still ours), so OUT holds nothing of it after.

Two writers that start within the same instant can both read their own token back; the
first check before a commit then stops one of them, before that commit. A writer that died
leaves a lease that expires after `LEASE_SECONDS` (or is deleted by hand, as its line says).
"""

from __future__ import annotations

import os
import secrets
import socket
import threading
import time

from .._errors import ConfigError
from ._fs import Location

LEASE_SECONDS = 300.0
"""A lease not renewed for this long is taken to be a dead writer's."""
RENEW_SECONDS = 60.0
"""How often a writer renews its lease (well within `LEASE_SECONDS`)."""


class Lease:
    """One writer's lease on an OUT in object storage (`take`, `check`, `release`)."""

    def __init__(self, path: Location, out: str) -> None:
        self.path = path
        self.out = out
        self.token = f"{socket.gethostname()} pid {os.getpid()} {secrets.token_hex(8)}".encode()
        self._stop = threading.Event()
        self._lost: str | None = None  # why the renewing thread found the lease gone
        self._thread: threading.Thread | None = None

    def _holder(self) -> tuple[bytes, float] | None:
        """The lease's token and its age in seconds (by the store's clock), or None."""
        info = self.path.fs.get_file_info(self.path.path)  # type: ignore[union-attr]
        if not info.is_file:
            return None
        try:
            token = self.path.read_bytes()[:256]
        except FileNotFoundError:
            return None
        return token, max(0.0, (time.time_ns() - (info.mtime_ns or 0)) / 1e9)

    def take(self) -> None:
        held = self._holder()
        if held is not None and held[0] != self.token and held[1] < LEASE_SECONDS:
            who = held[0].decode("utf-8", "replace")
            raise ConfigError(
                f"{self.out}: another vge replay is writing to this directory (its lock "
                f"{self.path} is held by {who}, renewed {held[1]:.0f} s ago; if none is running, "
                f"delete that object or wait {LEASE_SECONDS - held[1]:.0f} s)"
            )
        self.path.write_bytes(self.token)
        self.check()
        self._thread = threading.Thread(target=self._renew, name="vge-lease", daemon=True)
        self._thread.start()

    def _not_ours(self) -> str | None:
        """Why the lease is not ours any more, or None while it is."""
        held = self._holder()
        if held is None:
            return "deleted"
        return None if held[0] == self.token else "taken by another writer"

    def check(self) -> None:
        """Raise `ConfigError` (one line) unless the lease is still ours."""
        why = self._lost or self._not_ours()
        if why is not None:
            raise ConfigError(
                f"{self.out}: this vge replay lost its lock {self.path} ({why}): it stopped "
                "before committing anything more; run it again when the other one has ended"
            )

    def _renew(self) -> None:
        while not self._stop.wait(RENEW_SECONDS):
            try:
                why = self._not_ours()
                if why is None:
                    self.path.write_bytes(self.token)
            except OSError as exc:
                why = f"not renewed: {exc}"
            if why is not None:
                self._lost = why
                return

    def release(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        held = self._holder()
        if held is not None and held[0] == self.token:
            self.path.unlink(missing_ok=True)


__all__ = ["LEASE_SECONDS", "RENEW_SECONDS", "Lease"]
