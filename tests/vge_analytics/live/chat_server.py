"""A scripted OpenAI-compatible chat server on 127.0.0.1 (stdlib `http.server` in a thread):
each POST to `/v1/chat/completions` gets the next scripted reply, and the requests are kept.
GET `/v1/models` lists the models given (or answers the reply given instead: a refusal, or
404 as a server without that endpoint does)."""

from __future__ import annotations

import json
import threading
from collections.abc import Iterator
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
    """The chat requests (POST), in order."""
    listings: int = 0
    """GET /v1/models requests."""


@contextmanager
def chat_server(replies: list[Scripted], models: Scripted = SERVED) -> Iterator[Server]:
    """Serve `replies` in order (an exhausted script answers 500); `models` to GET
    /v1/models."""
    lock = threading.Lock()
    state: Server

    class Handler(BaseHTTPRequestHandler):
        def do_GET(self) -> None:  # noqa: N802 - http.server's name
            with lock:
                state.listings += 1
            self._send(state.models if self.path.rstrip("/").endswith("/models") else _NOT_FOUND)

        def do_POST(self) -> None:  # noqa: N802 - http.server's name
            length = int(self.headers.get("Content-Length", "0"))
            request = json.loads(self.rfile.read(length) or b"{}")
            with lock:
                state.requests.append({"path": self.path, "body": request})
                reply = state.replies.pop(0) if state.replies else error(500, "script ended")
            self._send(reply)

        def _send(self, reply: Scripted) -> None:
            self.send_response(reply.status)
            self.send_header("Content-Type", "application/json")
            self.send_header("Content-Length", str(len(reply.body)))
            for name, value in reply.headers:
                self.send_header(name, value)
            self.end_headers()
            self.wfile.write(reply.body)

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
