"""The chat client's waits between attempts, against a real HTTP server on 127.0.0.1: the
doubling wait with its jitter, and the server's `Retry-After` when it asks for longer."""

from __future__ import annotations

import inspect
import json
import time

import pytest

from vge_analytics._errors import InfrastructureError
from vge_analytics.live import ClientSettings
from vge_analytics.live._openai import ChatClient

from .chat_server import Scripted, answer, chat_server

MESSAGES = [{"role": "user", "content": "Boil the water."}]


def _refusal(status: int, retry_after: str | None) -> Scripted:
    body = json.dumps({"error": {"message": "busy", "type": "test", "code": None}}).encode()
    headers = (("Retry-After", retry_after),) if retry_after is not None else ()
    return Scripted(status, body, headers)


def _client(url: str, retries: int, jitters: list[float]) -> tuple[ChatClient, list[float]]:
    slept: list[float] = []
    draws = iter(jitters)
    settings = ClientSettings(base_url=url, retries=retries, retry_wait=1.0, timeout=10.0)
    client = ChatClient("m", settings, sleep=slept.append, jitter=lambda: next(draws))
    return client, slept


def test_waits_double_with_jitter_and_follow_retry_after(monkeypatch) -> None:
    monkeypatch.delenv("OPENAI_API_KEY", raising=False)
    script = [_refusal(429, "0"), _refusal(500, "7"), _refusal(503, None), answer("Timed_wait()")]
    with chat_server(script) as server:
        client, slept = _client(server.url, retries=3, jitters=[0.0, 0.5, 0.75])
        completion = client.complete(MESSAGES)
    assert completion.text == "Timed_wait()"
    assert len(server.requests) == 4
    # 1 s x 2^k, times (1 + jitter) / 2:  0.5;  1.5, but Retry-After asks 7;  3.5.
    assert slept == [0.5, 7.0, 3.5]


def test_the_last_failure_is_not_waited_for(monkeypatch) -> None:
    monkeypatch.delenv("OPENAI_API_KEY", raising=False)
    with chat_server([_refusal(503, None)] * 3) as server:
        client, slept = _client(server.url, retries=2, jitters=[0.999, 0.0, 0.5])
        with pytest.raises(
            InfrastructureError,
            match=r"no answer from http://127.0.0.1:\d+/v1 after 3 attempt\(s\)",
        ):
            client.complete(MESSAGES)
    assert slept == [pytest.approx(0.9995), 1.0]  # nothing after the third attempt


def test_the_default_jitter_stays_between_half_and_all_of_each_wait(monkeypatch) -> None:
    monkeypatch.delenv("OPENAI_API_KEY", raising=False)
    slept: list[float] = []
    with chat_server([_refusal(503, None)] * 4) as server:
        settings = ClientSettings(base_url=server.url, retries=3, retry_wait=2.0, timeout=10.0)
        client = ChatClient("m", settings, sleep=slept.append)
        with pytest.raises(InfrastructureError):
            client.complete(MESSAGES)
    assert len(slept) == 3
    for k, wait in enumerate(slept):
        assert 2.0 * 2**k / 2 <= wait < 2.0 * 2**k, (k, wait)


def test_vge_run_defaults_are_the_clients() -> None:
    """`vge run`'s options default to what `ClientSettings` does (one value, said twice: the
    command does not import the client until it runs)."""
    from vge_analytics.commands.run import run_command

    options = inspect.signature(run_command).parameters
    defaults = ClientSettings()
    for name in ("timeout", "max_response_bytes", "retries", "retry_wait"):
        assert options[name].default == getattr(defaults, name), name
    assert defaults.max_response_bytes == 4 * 1024 * 1024


def test_a_request_the_server_reads_slowly_ends_at_its_deadline(monkeypatch) -> None:
    """A request of 40 MB (far more than the socket buffers hold) to a server that reads
    256 KiB every 0.1 s: each write goes on within its own timeout, the request would take
    16 s to send; the deadline of 5 s ends it, so the server never reads it whole (it reads
    what was on the way when the client left, then the end of the connection)."""
    monkeypatch.delenv("OPENAI_API_KEY", raising=False)
    text = "x" * 40_000_000
    with chat_server([], read_every=0.1) as server:
        settings = ClientSettings(base_url=server.url, retries=0, timeout=5.0)
        client = ChatClient("m", settings)
        with pytest.raises(InfrastructureError, match=r"last: no whole answer within 5 s$"):
            client.complete([{"role": "user", "content": text}])
        for _ in range(600):  # the server reads on until the end of the connection
            if server.read:
                break
            time.sleep(0.1)
    assert len(server.requests) == 0
    assert server.read and server.read[0] < len(text), server.read
