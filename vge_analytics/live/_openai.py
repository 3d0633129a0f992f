"""A chat-completions client for any server that speaks the OpenAI API (hosted APIs, vLLM,
SGLang, Ollama, ...), with the one retry policy of `vge run`.

Every request has a timeout. A rate limit (429), a server error (5xx), a timeout, a lost
connection or an answer that cannot be read is retried, up to `retries` more times, waiting
about `retry_wait` seconds and doubling each time (or what the server's `Retry-After` asks,
when longer). Each wait is drawn between half and all of its doubled value ("equal jitter"),
so the threads of `--concurrency N`, refused together, do not all come back together. A request that still fails raises `InfrastructureError`: the harness ends that
episode as an infrastructure failure, never as the agent's. A key, model or address the
service refuses (401, 403, 404) raises `AgentError` at once: every request would fail alike.
"""

from __future__ import annotations

import os
import random
import time
from collections.abc import Callable
from dataclasses import dataclass

import msgspec
import openai

from .._errors import AgentError, InfrastructureError


class ClientSettings(msgspec.Struct, frozen=True):
    """How to reach a model and how patiently."""

    base_url: str | None = None
    """Server address (e.g. `http://127.0.0.1:8000/v1`); None: the OpenAI API."""
    temperature: float | None = None
    """None: the server's default."""
    max_tokens: int | None = None
    """Longest answer; None: the server's default."""
    timeout: float = 120.0
    """Seconds one request may take."""
    retries: int = 4
    """Further attempts after a failed request."""
    retry_wait: float = 2.0
    """Seconds before the first retry; doubles with each."""


@dataclass(frozen=True, slots=True)
class Completion:
    """One answered request."""

    text: str
    prompt_tokens: int | None
    completion_tokens: int | None
    latency_seconds: float
    """Of the request that succeeded."""
    timestamp: float
    """When the answer arrived, seconds since the epoch."""


def api_key(base_url: str | None) -> str:
    """`OPENAI_API_KEY`; servers on your own address often need none, and get a placeholder."""
    key = os.environ.get("OPENAI_API_KEY", "").strip()
    if key:
        return key
    if base_url is None:
        raise AgentError("openai agent: set OPENAI_API_KEY (or give --base-url for a local server)")
    return "no-key"


class ChatClient:
    """Sends chat requests; safe to share between threads (the `openai` client is)."""

    def __init__(
        self,
        model: str,
        settings: ClientSettings,
        *,
        sleep: Callable[[float], None] = time.sleep,
        jitter: Callable[[], float] = random.random,
    ) -> None:
        self.model = model
        self.settings = settings
        self._sleep = sleep
        self._jitter = jitter
        """A number in [0, 1) per wait (tests fix it)."""
        # Retries are ours (one policy, counted here), so the library makes one attempt.
        self._client = openai.OpenAI(
            api_key=api_key(settings.base_url),
            base_url=settings.base_url,
            timeout=settings.timeout,
            max_retries=0,
        )

    def complete(self, messages: list[dict]) -> Completion:
        """The model's answer to `messages`; raises `InfrastructureError` when every attempt
        failed, `AgentError` when the service refuses the request for good."""
        s = self.settings
        extra: dict = {}
        if s.temperature is not None:
            extra["temperature"] = s.temperature
        if s.max_tokens is not None:
            extra["max_tokens"] = s.max_tokens
        reasons: list[str] = []
        for attempt in range(s.retries + 1):
            asked = 0.0  # what the server's Retry-After asks
            started = time.perf_counter()
            try:
                response = self._client.chat.completions.create(
                    model=self.model, messages=messages, **extra
                )
                latency = time.perf_counter() - started
                completion = _read(response, latency)
            except (openai.AuthenticationError, openai.PermissionDeniedError) as exc:
                raise AgentError(
                    f"openai agent: the service refused the key: {_say(exc)}"
                ) from None
            except openai.NotFoundError as exc:
                raise AgentError(
                    f"openai agent: no model {self.model!r} at {s.base_url or 'the OpenAI API'}: "
                    f"{_say(exc)}"
                ) from None
            except (openai.RateLimitError, openai.InternalServerError) as exc:
                reasons.append(_say(exc))
                asked = _retry_after(exc)
            except openai.APIConnectionError as exc:  # timeouts included
                reasons.append(_say(exc))
            except openai.APIStatusError as exc:  # another 4xx: this request will not pass
                raise InfrastructureError(f"request refused: {_say(exc)}") from None
            except (openai.APIError, _Unreadable, ValueError) as exc:  # a body that is not JSON
                reasons.append(f"unreadable answer: {_say(exc)}")
            else:
                return completion
            if attempt < s.retries:
                wait = s.retry_wait * (2**attempt) * (1.0 + self._jitter()) / 2.0
                self._sleep(max(wait, asked))
        raise InfrastructureError(
            f"no answer after {s.retries + 1} attempt(s); last: {reasons[-1]}"
        )


class _Unreadable(Exception):
    """The server answered 200 with something that is not a chat completion."""


def _read(response: object, latency: float) -> Completion:
    try:
        message = response.choices[0].message  # type: ignore[attr-defined]
    except (AttributeError, IndexError, TypeError):
        raise _Unreadable(f"no choices in {str(response)[:120]!r}") from None
    usage = getattr(response, "usage", None)
    return Completion(
        text=message.content or "",
        prompt_tokens=getattr(usage, "prompt_tokens", None),
        completion_tokens=getattr(usage, "completion_tokens", None),
        latency_seconds=latency,
        timestamp=time.time(),
    )


def _retry_after(exc: openai.APIStatusError) -> float:
    value = exc.response.headers.get("retry-after", "")
    try:
        return min(float(value), 300.0)
    except ValueError:
        return 0.0


def _say(exc: Exception) -> str:
    """One line for people: the status when there is one, then the message."""
    status = getattr(exc, "status_code", None)
    text = " ".join(str(exc).split())[:300]
    return f"HTTP {status}: {text}" if status is not None else f"{type(exc).__name__}: {text}"


__all__ = ["ChatClient", "ClientSettings", "Completion", "api_key"]
