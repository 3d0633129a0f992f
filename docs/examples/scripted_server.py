"""A scripted OpenAI-compatible chat server on 127.0.0.1, for trying `vge run --agent openai:...`
without a model: each chat request gets the next reply of a script, with the token counts the
script gives; the replies a real server sends when it fails (HTTP 500) are scripted the same way.

    URL=$(python docs/examples/scripted_server.py docs/examples/cost/priced.json)
    vge run logs/bench --agent openai:scripted-vlm --base-url "$URL" ...

It listens on a free port of 127.0.0.1, prints its base URL (`http://127.0.0.1:PORT/v1`) and
goes on in the background, so the shell continues; it stops once every reply of the script
has been sent, or after two minutes without a request. A script is a JSON object:

    {"model": "scripted-vlm",
     "replies": [{"content": "Thinking: ...\\nAction: Press(coord=[10, 20], params=[1])",
                  "prompt_tokens": 1200, "completion_tokens": 30},
                 {"status": 500, "message": "overloaded"}]}

`GET /v1/models` lists the model; `POST /v1/chat/completions` answers the next reply (a
`content` reply as a chat completion with its usage; a `status` reply as that HTTP error).
Standard library only. docs/ANALYSIS.md ("Cost and completeness") runs it.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

IDLE_SECONDS = 120.0
"""The server stops after this long without a request (it never lingers)."""
MAX_BODY = 256 * 1024**2
"""The longest request read (bytes): a prompt with its pictures fits many times over."""
MAX_SCRIPT = 16 * 1024**2
"""The largest script file read (bytes)."""


def load_script(path: Path) -> tuple[str, list[dict]]:
    """The model name and the replies of a script file (one line naming the problem)."""
    if path.stat().st_size > MAX_SCRIPT:
        raise SystemExit(f"{path}: larger than {MAX_SCRIPT} bytes")
    try:
        script = json.loads(path.read_text(encoding="utf-8"))
        model, replies = str(script["model"]), list(script["replies"])
    except (ValueError, KeyError, TypeError) as exc:
        raise SystemExit(f"{path}: not a script ({exc})") from None
    for k, reply in enumerate(replies):
        if not isinstance(reply, dict) or not ("content" in reply or "status" in reply):
            raise SystemExit(f"{path}: reply {k} has neither content nor status")
    return model, replies


def completion(model: str, reply: dict) -> tuple[int, bytes]:
    """The HTTP status and body of one scripted reply."""
    if "status" in reply:
        error = {"message": str(reply.get("message", "")), "type": "scripted", "code": None}
        return int(reply["status"]), json.dumps({"error": error}).encode()
    prompt, completion_tokens = int(reply["prompt_tokens"]), int(reply["completion_tokens"])
    body = {
        "id": "chatcmpl-scripted",
        "object": "chat.completion",
        "created": 0,
        "model": model,
        "choices": [
            {
                "index": 0,
                "message": {"role": "assistant", "content": str(reply["content"])},
                "finish_reason": "stop",
            }
        ],
        "usage": {
            "prompt_tokens": prompt,
            "completion_tokens": completion_tokens,
            "total_tokens": prompt + completion_tokens,
        },
    }
    return 200, json.dumps(body).encode()


def serve(server: ThreadingHTTPServer, model: str, replies: list[dict]) -> None:
    """Answer requests until the script is used up or the server has been idle too long."""
    lock = threading.Lock()
    used_up = threading.Event()
    active = threading.Event()

    class Handler(BaseHTTPRequestHandler):
        def do_GET(self) -> None:  # noqa: N802 - http.server's name
            active.set()
            if self.path.rstrip("/").endswith("/models"):
                listing = {"object": "list", "data": [{"id": model, "object": "model"}]}
                self._send(200, json.dumps(listing).encode())
            else:
                self._send(404, b'{"detail": "Not Found"}')

        def do_POST(self) -> None:  # noqa: N802 - http.server's name
            active.set()
            length = int(self.headers.get("Content-Length") or 0)
            if not 0 <= length <= MAX_BODY:
                self._send(413, b'{"error": {"message": "request too large"}}')
                return
            while length > 0:  # read (and drop) the prompt
                chunk = self.rfile.read(min(length, 1 << 20))
                if not chunk:
                    break
                length -= len(chunk)
            with lock:
                reply = replies.pop(0) if replies else {"status": 500, "message": "script ended"}
                last = not replies
            self._send(*completion(model, reply))
            if last:
                used_up.set()

        def _send(self, status: int, body: bytes) -> None:
            self.send_response(status)
            self.send_header("Content-Type", "application/json")
            self.send_header("Content-Length", str(len(body)))
            if status >= 500:
                self.send_header("Retry-After", "0")
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, format: str, *args: object) -> None:  # noqa: A002
            return None

    server.RequestHandlerClass = Handler
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    while not used_up.wait(IDLE_SECONDS):
        if not active.is_set():
            break
        active.clear()
    server.shutdown()
    server.server_close()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("script", type=Path, help="the script: a JSON file (above)")
    parser.add_argument("--port", type=int, default=0, help="port (default: a free one)")
    parser.add_argument(
        "--foreground", action="store_true", help="stay in the foreground (default: detach)"
    )
    args = parser.parse_args(argv)
    model, replies = load_script(args.script)
    server = ThreadingHTTPServer(("127.0.0.1", args.port), BaseHTTPRequestHandler)
    url = f"http://127.0.0.1:{server.server_address[1]}/v1"
    if not args.foreground and os.fork() > 0:
        print(url, flush=True)  # listening already: the next command can connect
        return 0
    if not args.foreground:  # the background server: off the terminal, its own session
        os.setsid()
        devnull = os.open(os.devnull, os.O_RDWR)
        for fd in (0, 1, 2):
            os.dup2(devnull, fd)
    else:
        print(url, flush=True)
    serve(server, model, replies)
    return 0


if __name__ == "__main__":
    sys.exit(main())
