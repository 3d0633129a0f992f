"""The HTTP client under the chat client (`_openai.py`), with the two bounds a broken or
hostile server must not pass (PROTOCOL §10.3):

- a **deadline** per request: the request, its answer and any redirect on the way end
  within the request's time (`--timeout`) from its first operation on the network
  (connecting included), however the server spreads its bytes out; a server that trickles
  its answer a byte at a time (each read in time, the answer never done) is cut off there;
- a **cap** on the bytes received for one request (`--max-response-bytes`: status line,
  headers and body, an error's body included): past it the answer is dropped, so an answer
  of a gigabyte costs the cap in memory, not a gigabyte.

The HTTP library `openai` is built on (httpx; httpx2 in its later releases) has neither: its
timeouts are per read, and it reads a whole body before `openai` sees it. So the bounds are
kept where every byte passes, in the network backend of each of the client's connection
pools (the direct one and those of the proxies the environment names): each socket read is
counted against the cap, and a watchdog shuts down the socket an operation is blocked on
when its request's time is up. A request is sent and read on the thread that makes it (the
client is synchronous), so the bounds are per thread (`RequestBounds.request`) and the
threads of `--concurrency N` each have their own.

Answers are asked for uncompressed (`Accept-Encoding: identity`): the cap counts the bytes
received, and a compressed body could inflate far past it. An answer compressed all the
same is refused before its body is read.
"""

from __future__ import annotations

import contextlib
import socket
import threading
import time
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from typing import Any

import openai


class AnswerDropped(Exception):
    """The server's answer was cut off or refused unread: its request passed its deadline
    (`late`) or its cap, or it came compressed. The message says which, for people."""

    def __init__(self, message: str, *, late: bool = False) -> None:
        super().__init__(message)
        self.late = late


class _Budget:
    """What one request may still take: time and bytes. Its time runs from its first
    network operation (what the client does before, building the request, is not the
    server's to pay for); the watchdog (a timer) then marks it expired when the time is up
    and interrupts the socket operation in progress, if any."""

    def __init__(self, seconds: float, max_bytes: int) -> None:
        self.seconds = seconds
        self.max_bytes = max_bytes
        self.received = 0
        self.deadline = float("inf")
        """Set by the first network operation."""
        self.expired = False
        self._lock = threading.Lock()
        self._busy: Any = None
        """The network stream an operation of this request is blocked on, if any."""
        self._timer = threading.Timer(seconds, self._expire)
        self._timer.daemon = True

    def _start(self) -> None:
        """Start the clock, at the first network operation (under the lock)."""
        if self.deadline == float("inf"):
            self.deadline = time.monotonic() + self.seconds
            self._timer.start()

    def end(self) -> None:
        self._timer.cancel()  # harmless when it never started

    def _expire(self) -> None:
        with self._lock:
            self.expired = True
            if self._busy is not None:
                _interrupt(self._busy)

    def late(self) -> AnswerDropped:
        return AnswerDropped(f"no whole answer within {self.seconds:g} s", late=True)

    def past(self) -> bool:
        """The deadline has passed (the watchdog may not have run yet: a read's own
        timeout, which started later, can end it first)."""
        return self.expired or time.monotonic() >= self.deadline

    def left(self, timeout: float | None) -> float:
        """`timeout`, shortened to the time left (for connecting: no socket to interrupt)."""
        with self._lock:
            self._start()
        left = self.deadline - time.monotonic()
        if left <= 0:
            raise self.late()
        return left if timeout is None else min(timeout, left)

    @contextmanager
    def operation(self, stream: Any) -> Iterator[None]:
        """One socket operation on `stream`, which the watchdog interrupts at the deadline."""
        with self._lock:
            self._start()
            if self.expired:
                raise self.late()
            self._busy = stream
        try:
            yield
        except Exception as exc:
            if self.past():
                raise self.late() from exc
            raise
        finally:
            with self._lock:
                self._busy = None
        if self.expired:  # an interrupted read ends as if the server had closed
            raise self.late()

    def took(self, received: int) -> None:
        self.received += received
        if self.received > self.max_bytes:
            raise AnswerDropped(
                f"an answer of more than {self.max_bytes:,} bytes (--max-response-bytes)"
            )


def _interrupt(stream: Any) -> None:
    """Wake the operation blocked on `stream`: shut its socket down (the connection is then
    dropped). The base class's `shutdown`: a TLS socket's own would drop its TLS state
    under the thread reading it."""
    sock = stream.get_extra_info("socket")
    if sock is not None:
        with contextlib.suppress(OSError):  # already closed
            socket.socket.shutdown(sock, socket.SHUT_RDWR)


class RequestBounds:
    """The deadline and the cap of the requests made on each thread."""

    def __init__(self, max_bytes: int) -> None:
        self.max_bytes = max_bytes
        self._local = threading.local()

    @contextmanager
    def request(self, seconds: float) -> Iterator[None]:
        """What the block sends and reads (one request, with its redirects) ends within
        `seconds` and receives at most `max_bytes`; else `AnswerDropped`."""
        budget = _Budget(seconds, self.max_bytes)
        self._local.budget = budget
        try:
            yield
        finally:
            budget.end()
            self._local.budget = None

    def current(self) -> _Budget | None:
        return getattr(self._local, "budget", None)

    def http_client(self) -> Any:
        """A client of the library `openai` uses, with `openai`'s defaults (connection
        limits, redirects, proxies from the environment), whose every connection keeps the
        bounds."""
        client = openai.DefaultHttpxClient(
            headers={"Accept-Encoding": "identity"},
            event_hooks={"response": [_uncompressed]},
        )
        for transport in [client._transport, *client._mounts.values()]:
            if transport is None:
                continue
            pool = getattr(transport, "_pool", None)
            backend = getattr(pool, "_network_backend", None)
            if backend is None:
                raise RuntimeError(
                    f"{type(client).__module__}: the HTTP client keeps its connections where "
                    "`vge run` cannot bound them"
                )
            pool._network_backend = _Backend(backend, self)
        return client


def _uncompressed(response: Any) -> None:
    """Refuse a compressed answer before its body is read (the cap counts bytes received)."""
    encoding = response.headers.get("content-encoding", "identity").strip().lower()
    if encoding not in ("", "identity"):
        response.close()
        raise AnswerDropped(f"a compressed answer ({encoding}), though none was asked for")


class _Backend:
    """A network backend whose streams keep the bounds of the thread that uses them."""

    def __init__(self, inner: Any, bounds: RequestBounds) -> None:
        self._inner = inner
        self._bounds = bounds

    def connect_tcp(
        self,
        host: str,
        port: int,
        timeout: float | None = None,
        local_address: str | None = None,
        socket_options: Iterable[Any] | None = None,
    ) -> _Stream:
        stream = self._inner.connect_tcp(
            host,
            port,
            timeout=self._timeout(timeout),
            local_address=local_address,
            socket_options=socket_options,
        )
        return _Stream(stream, self._bounds)

    def connect_unix_socket(
        self, path: str, timeout: float | None = None, socket_options: Iterable[Any] | None = None
    ) -> _Stream:
        stream = self._inner.connect_unix_socket(
            path, timeout=self._timeout(timeout), socket_options=socket_options
        )
        return _Stream(stream, self._bounds)

    def _timeout(self, timeout: float | None) -> float | None:
        """Connecting: no socket yet for the watchdog, so the timeout ends at the deadline."""
        budget = self._bounds.current()
        return timeout if budget is None else budget.left(timeout)

    def sleep(self, seconds: float) -> None:
        self._inner.sleep(seconds)


class _Stream:
    """A connection's stream: its operations count against the current request's budget
    (none: a request made outside `RequestBounds.request`, unbounded)."""

    def __init__(self, inner: Any, bounds: RequestBounds) -> None:
        self._inner = inner
        self._bounds = bounds

    def read(self, max_bytes: int, timeout: float | None = None) -> bytes:
        budget = self._bounds.current()
        if budget is None:
            return self._inner.read(max_bytes, timeout)
        with budget.operation(self._inner):
            data = self._inner.read(max_bytes, timeout)
        budget.took(len(data))
        return data

    def write(self, buffer: bytes, timeout: float | None = None) -> None:
        budget = self._bounds.current()
        if budget is None:
            return self._inner.write(buffer, timeout)
        with budget.operation(self._inner):
            self._inner.write(buffer, timeout)

    def start_tls(
        self, ssl_context: Any, server_hostname: str | None = None, timeout: float | None = None
    ) -> Any:
        budget = self._bounds.current()
        if budget is None:
            tls = self._inner.start_tls(ssl_context, server_hostname, timeout)
        else:
            with budget.operation(self._inner):
                tls = self._inner.start_tls(ssl_context, server_hostname, timeout)
        return _Stream(tls, self._bounds)

    def close(self) -> None:
        self._inner.close()

    def get_extra_info(self, info: str) -> Any:
        return self._inner.get_extra_info(info)


__all__ = ["AnswerDropped", "RequestBounds"]
