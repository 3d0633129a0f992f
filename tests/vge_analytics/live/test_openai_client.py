"""The chat client's waits between attempts, against a real HTTP server on 127.0.0.1: the
doubling wait with its jitter, and the server's `Retry-After` when it asks for longer."""

from __future__ import annotations

import json

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
        with pytest.raises(InfrastructureError, match=r"no answer after 3 attempt\(s\)"):
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
