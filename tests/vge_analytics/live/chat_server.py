"""A scripted OpenAI-compatible chat server on 127.0.0.1 (stdlib `http.server` in a thread):
each POST to `/v1/chat/completions` gets the next scripted reply, and the requests are kept.
GET `/v1/models` lists the models given (or answers the reply given instead: a refusal, or
404 as a server without that endpoint does).

Hostile replies (`Streamed`) are written as they are made, never held whole: an answer of a
gigabyte (`huge`), or one a byte at a time (`trickle`), stopping when the client goes."""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer


@dataclass(frozen=True)
class Scripted:
    status: int
    body: bytes
    headers: tuple[tuple[str, str], ...] = ()


def answer(text: str, prompt_tokens: int = 1000, completion_tokens: int = 50) -> Scripted:
    """A chat completion whose message is `text`, with its token usage."""
    body = {
        "id": "chatcmpl-test",
        "object": "chat.completion",
        "created": 0,
        "model": "scripted",
        "choices": [
            {
                "index": 0,
                "message": {"role": "assistant", "content": text},
                "finish_reason": "stop",
            }
        ],
        "usage": {
            "prompt_tokens": prompt_tokens,
            "completion_tokens": completion_tokens,
            "total_tokens": prompt_tokens + completion_tokens,
        },
    }
    return Scripted(200, json.dumps(body).encode())


@dataclass(frozen=True)
class Streamed:
    """A reply written piece by piece as `pieces()` makes them: the status line and headers
    first (`head`), then the body; `length`, the Content-Length it declares (None: none, the
    body ends when the connection closes)."""

    head: bytes
    pieces: Callable[[], Iterator[bytes]]
    length: int | None = None


_COMPLETION_HEAD = (
    b'{"id": "chatcmpl-test", "object": "chat.completion", "created": 0, "model": "scripted", '
    b'"choices": [{"index": 0, "finish_reason": "stop", "message": {"role": "assistant", '
    b'"content": "'
)
_COMPLETION_TAIL = b'"}}], "usage": {"prompt_tokens": 1, "completion_tokens": 1}}'


def huge(size: int, status: int = 200, declared: bool = True) -> Streamed:
    """A chat completion of `size` bytes (its text `x` repeated), made 1 MiB at a time; with
    `declared`, its Content-Length says so, else the body ends with the connection."""
    fill = size - len(_COMPLETION_HEAD) - len(_COMPLETION_TAIL)

    def pieces() -> Iterator[bytes]:
        yield _COMPLETION_HEAD
        block = b"x" * (1 << 20)
        left = fill
        while left > 0:
            yield block[:left]
            left -= len(block)
        yield _COMPLETION_TAIL

    head = f"HTTP/1.0 {status} X\r\nContent-Type: application/json\r\n".encode()
    return Streamed(head, pieces, size if declared else None)


def trickle(every: float, where: str = "body", size: int = 240) -> Streamed:
    """One byte every `every` seconds, `size` of them: in the body (after the headers, whose
    Content-Length promises `size` bytes), or in the headers themselves (`where="headers"`)."""
    if where == "headers":
        head, body = b"", b"HTTP/1.0 200 OK\r\nX-Slow: " + b"a" * size
    else:
        head, body = b"HTTP/1.0 200 OK\r\nContent-Type: application/json\r\n", b" " * size

    def pieces() -> Iterator[bytes]:
        for byte in body:
            yield bytes([byte])
            time.sleep(every)

    return Streamed(head, pieces, size if where == "body" else None)


def error(status: int, message: str) -> Scripted:
    body = json.dumps({"error": {"message": message, "type": "test", "code": None}}).encode()
    return Scripted(status, body, (("Retry-After", "0"),))


NOT_JSON = Scripted(200, b"<html>upstream hiccup</html>")
"""A 200 whose body is not a chat completion."""
_NOT_FOUND = Scripted(404, b'{"detail": "Not Found"}')
"""What FastAPI servers (vLLM, LiteLLM) answer on a path they do not serve."""


def model_list(*names: str) -> Scripted:
    """What `GET /v1/models` answers: the models `names`."""
    body = {
        "object": "list",
        "data": [{"id": n, "object": "model", "owned_by": "test"} for n in names],
    }
    return Scripted(200, json.dumps(body).encode())


SERVED = model_list("scripted-vlm")
"""The model every test asks for."""


@dataclass
class Server:
    url: str
    replies: list[Scripted]
    models: Scripted
    requests: list[dict] = field(default_factory=list)
    """The chat requests (POST), in order (the body of one over 1 MB is not kept: None)."""
    listings: int = 0
    """GET /v1/models requests."""
    read: list[int] = field(default_factory=list)
    """With `read_every`: the bytes of each request's body read before it ended."""


@contextmanager
def chat_server(
    replies: list[Scripted | Streamed],
    models: Scripted = SERVED,
    then: Scripted | Streamed | None = None,
    read_every: float = 0.0,
) -> Iterator[Server]:
    """Serve `replies` in order, then `then` to every request (None: 500, the script
    ended); `models` to GET /v1/models. With `read_every`, a server that reads a request's
    body slowly, 256 KiB every `read_every` seconds (each write of the client goes on), until
    it has it whole or the client goes away (`Server.read`)."""
    lock = threading.Lock()
    state: Server

    class Handler(BaseHTTPRequestHandler):
        def do_GET(self) -> None:  # noqa: N802 - http.server's name
            with lock:
                state.listings += 1
            self._send(state.models if self.path.rstrip("/").endswith("/models") else _NOT_FOUND)

        def do_POST(self) -> None:  # noqa: N802 - http.server's name
            length = int(self.headers.get("Content-Length", "0"))
            if read_every:
                body = self._read_slowly(length)
                if len(body) < length:
                    self.close_connection = True
                    return
            else:
                body = self.rfile.read(length)
            request = json.loads(body or b"{}") if length <= 1 << 20 else None
            with lock:
                state.requests.append({"path": self.path, "body": request})
                reply = state.replies.pop(0) if state.replies else then
            self._send(error(500, "script ended") if reply is None else reply)

        def _read_slowly(self, length: int) -> bytes:
            pieces: list[bytes] = []
            got = 0
            while got < length and (piece := self.rfile.read1(min(1 << 18, length - got))):
                pieces.append(piece)
                got += len(piece)
                time.sleep(read_every)
            state.read.append(got)
            return b"".join(pieces)

        def _send(self, reply: Scripted | Streamed) -> None:
            if isinstance(reply, Streamed):
                self._stream(reply)
                return
            self.send_response(reply.status)
            self.send_header("Content-Type", "application/json")
            self.send_header("Content-Length", str(len(reply.body)))
            for name, value in reply.headers:
                self.send_header(name, value)
            self.end_headers()
            self.wfile.write(reply.body)

        def _stream(self, reply: Streamed) -> None:
            length = b"" if reply.length is None else b"Content-Length: %d\r\n" % reply.length
            try:
                if reply.head:
                    self.wfile.write(reply.head + length + b"\r\n")
                for piece in reply.pieces():
                    self.wfile.write(piece)
                    self.wfile.flush()
            except (BrokenPipeError, ConnectionResetError):
                pass  # the client went away: what it did not read is never made
            self.close_connection = True

        def log_message(self, format: str, *args: object) -> None:  # noqa: A002
            return None

    httpd = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    state = Server(f"http://127.0.0.1:{httpd.server_address[1]}/v1", list(replies), models)
    thread = threading.Thread(target=httpd.serve_forever, daemon=True)
    thread.start()
    try:
        yield state
    finally:
        httpd.shutdown()
        httpd.server_close()
        thread.join()
