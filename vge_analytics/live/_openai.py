"""A chat-completions client for any server that speaks the OpenAI API (hosted APIs, vLLM,
SGLang, Ollama, ...), with the one retry policy of `vge run` (PROTOCOL §10.3).

`check` asks the server once before the first episode: its list of models, and one minimal
request when the model is not listed there (aliases and wildcard routes are not always
listed). A server that cannot be reached, a refused key or an unknown model fail there, in
one line, before anything is played.

Every request ends within its time (`timeout`, in all: not per read) and receives at most
`max_response_bytes` (`_http.py`), and an answer's text and token counts must be what a
step of the log may hold (PROTOCOL §1.4). A server error (5xx), a rate limit (429), a
request timeout (408), a conflict (409), a lost connection, a request past its time, or an
answer that cannot be read (not a chat completion, past the cap, out of the protocol's
bounds) is retried, up to `retries` more times, waiting about `retry_wait` seconds and
doubling each time (or what the server's `Retry-After` asks, when longer). Each wait is
drawn between half and all of its doubled value ("equal jitter"), so the threads of
`--concurrency N`, refused together, do not all come back together; a run that is stopping
cuts the wait short. A request that still fails raises `InfrastructureError`: the harness
ends that episode as an infrastructure failure, never as the agent's. Any other 4xx is never
retried (`_refusal.py`): a request longer than the model's context window raises
`ContextExceededError` (the episode ends there), anything else `RequestRefusedError` (every
request would be refused alike).
"""

from __future__ import annotations

import os
import random
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import msgspec
import openai

import replay

from .._errors import (
    AgentError,
    ContextExceededError,
    InfrastructureError,
    RequestRefusedError,
    ServerUnreachableError,
)
from ._http import AnswerDropped, RequestBounds
from ._refusal import Refusal, error_message, refusal

CHECK_TIMEOUT = 10.0
"""Seconds the list of models may take when the server is checked (a request's own timeout
when that is shorter): a server that answers nothing is not waited for as long as a model."""
CHECK_MESSAGE = "Reply with the word OK."
"""The minimal request of `check`, sent with the run's own parameters."""
MAX_RESPONSE_BYTES = 4 << 20
"""The most bytes one answer may take by default (4 MiB, about a million tokens of text):
far more than a step's answer needs, far less than the memory of the machine."""


class ClientSettings(msgspec.Struct, frozen=True):
    """How to reach a model and how patiently."""

    base_url: str | None = None
    """Server address (e.g. `http://127.0.0.1:8000/v1`); None: the OpenAI API."""
    temperature: float | None = None
    """None: the server's default."""
    max_tokens: int | None = None
    """Longest answer; None: the server's default."""
    timeout: float = 120.0
    """Seconds one request may take, in all: from sending it to the last byte of the answer
    (not per read: a server trickling its answer is cut off there)."""
    max_response_bytes: int = MAX_RESPONSE_BYTES
    """The most bytes the answer to one request may take (headers included); a longer one
    is dropped, as an answer that cannot be read."""
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
        sleep: Callable[[float], None] | None = None,
        jitter: Callable[[], float] = random.random,
    ) -> None:
        self.model = model
        self.settings = settings
        self._sleep = sleep
        """What waits between attempts (tests record the waits); None: a real wait, cut
        short when the run stops."""
        self._jitter = jitter
        """A number in [0, 1) per wait (tests fix it)."""
        self._bounds = RequestBounds(settings.max_response_bytes)
        # Retries are ours (one policy, counted here), so the library makes one attempt.
        self._client = openai.OpenAI(
            api_key=api_key(settings.base_url),
            base_url=settings.base_url,
            timeout=settings.timeout,
            max_retries=0,
            http_client=self._bounds.http_client(),
        )

    @property
    def where(self) -> str:
        return self.settings.base_url or "the OpenAI API"

    def _parameters(self) -> dict[str, Any]:
        s = self.settings
        extra: dict[str, Any] = {}
        if s.temperature is not None:
            extra["temperature"] = s.temperature
        if s.max_tokens is not None:
            extra["max_tokens"] = s.max_tokens
        return extra

    def check(self) -> None:
        """Fail fast, before the first episode: raises `ServerUnreachableError` when the
        server cannot be reached, `RequestRefusedError` when it refuses the key, does not
        know the model or refuses the run's parameters. One attempt each, no retries; a
        server that is reachable but busy (5xx, 429) passes: the run's retries deal with it."""
        listed: list[str] | None = None
        seconds = min(self.settings.timeout, CHECK_TIMEOUT)
        quick = self._client.with_options(timeout=seconds)
        try:
            with self._bounds.request(seconds):
                listed = [m.id for m in quick.models.list().data]
        except (openai.APIConnectionError, AnswerDropped) as exc:  # timeouts included
            self._check_unreachable(exc)
        except openai.APIStatusError as exc:
            if refusal(exc) == "key":
                raise self._refused("key", exc) from None
            # No list here (404 on a server without one, 5xx): the request below decides.
        except _UNREADABLE:
            pass  # a list that cannot be read: likewise
        if listed is not None and self.model in listed:
            return
        try:
            with self._bounds.request(self.settings.timeout):
                self._client.chat.completions.create(
                    model=self.model,
                    messages=[{"role": "user", "content": CHECK_MESSAGE}],
                    **self._parameters(),
                )
        except (openai.APIConnectionError, AnswerDropped) as exc:
            self._check_unreachable(exc)
        except openai.APIStatusError as exc:
            kind = refusal(exc)
            if kind != "retry":
                raise self._refused(kind, exc, listed) from None
        except _UNREADABLE:
            pass  # it answered: reachable, and the run's retries deal with the rest

    def complete(self, messages: list[dict], *, stop: threading.Event | None = None) -> Completion:
        """The model's answer to `messages`. Raises `InfrastructureError` when every attempt
        failed (or `stop` was set while waiting to retry), `ContextExceededError` when the
        request is longer than the model's context window, `RequestRefusedError` when the
        service refuses it for good."""
        s = self.settings
        extra = self._parameters()
        reasons: list[str] = []
        for attempt in range(s.retries + 1):
            asked = 0.0  # what the server's Retry-After asks
            started = time.perf_counter()
            try:
                with self._bounds.request(s.timeout):
                    response = self._client.chat.completions.create(
                        model=self.model, messages=messages, **extra
                    )
                latency = time.perf_counter() - started
                completion = _read(response, latency)
            except openai.APIStatusError as exc:
                kind = refusal(exc)
                if kind != "retry":
                    raise self._refused(kind, exc) from None
                reasons.append(_say(exc))
                asked = _retry_after(exc)
            except openai.APIConnectionError as exc:  # timeouts included
                dropped = _dropped(exc)
                reasons.append(_say(exc) if dropped is None else str(dropped))
            except AnswerDropped as exc:
                reasons.append(str(exc))
            except _UNREADABLE as exc:
                reasons.append(f"unreadable answer: {_say(exc)}")
            else:
                return completion
            if attempt < s.retries:
                wait = s.retry_wait * (2**attempt) * (1.0 + self._jitter()) / 2.0
                self._wait(max(wait, asked), stop)
        raise InfrastructureError(
            f"no answer from {self.where} after {s.retries + 1} attempt(s); last: {reasons[-1]}"
        )

    def _wait(self, seconds: float, stop: threading.Event | None) -> None:
        if self._sleep is not None:
            self._sleep(seconds)
        elif stop is not None:
            stop.wait(seconds)
        else:
            time.sleep(seconds)
        if stop is not None and stop.is_set():
            raise InfrastructureError("the run is stopping")

    def _check_unreachable(self, exc: openai.APIConnectionError | AnswerDropped) -> None:
        """A request of `check` that failed: raises `ServerUnreachableError` unless the
        server answered (an answer dropped past its cap or compressed: the run's retries
        deal with it)."""
        dropped = exc if isinstance(exc, AnswerDropped) else _dropped(exc)
        if dropped is None:
            said = _say(exc)
        elif dropped.late:
            said = str(dropped)
        else:
            return
        raise ServerUnreachableError(f"openai agent: cannot reach {self.where}: {said}") from None

    def _refused(
        self, kind: Refusal, exc: openai.APIStatusError, listed: list[str] | None = None
    ) -> ContextExceededError | RequestRefusedError:
        said = _say(exc)
        if kind == "context":
            return ContextExceededError(f"the request is longer than the model's context: {said}")
        if kind == "key":
            message = f"openai agent: the service refused the key: {said}"
        elif kind == "model":
            serves = f" (it serves {', '.join(map(repr, listed[:5]))})" if listed else ""
            message = f"openai agent: no model {self.model!r} at {self.where}{serves}: {said}"
        else:
            message = (
                f"openai agent: {self.where} refused the request, and would refuse every "
                f"request alike: {said}"
            )
        return RequestRefusedError(message, status=exc.status_code)


class _Unreadable(Exception):
    """The server answered 200 with something that is not a chat completion, or one a step
    of the log cannot hold."""


_UNREADABLE = (openai.APIError, _Unreadable, AnswerDropped, ValueError, RecursionError)
"""What an answer that cannot be read raises: not JSON (or nested past the parser's depth),
not a chat completion, out of the protocol's bounds."""


def _read(response: object, latency: float) -> Completion:
    try:
        message = response.choices[0].message  # type: ignore[attr-defined]
    except (AttributeError, IndexError, KeyError, TypeError):
        raise _Unreadable(f"no choices in {str(response)[:120]!r}") from None
    usage = getattr(response, "usage", None)
    # What the log will carry, checked by the log's own rule (PROTOCOL §1.4: the text is a
    # string, token counts are whole numbers from 0 to 2^40) before anything is written.
    try:
        step = msgspec.convert(
            {
                "output": getattr(message, "content", None) or "",
                "prompt_tokens": getattr(usage, "prompt_tokens", None),
                "completion_tokens": getattr(usage, "completion_tokens", None),
            },
            replay.LogStep,
        )
    except msgspec.ValidationError as exc:
        raise _Unreadable(f"an answer out of a step's bounds (PROTOCOL §1.4): {exc}") from None
    return Completion(
        text=step.output or "",
        prompt_tokens=step.prompt_tokens,
        completion_tokens=step.completion_tokens,
        latency_seconds=latency,
        timestamp=time.time(),
    )


def _dropped(exc: openai.APIConnectionError) -> AnswerDropped | None:
    """The bound a request passed, when the `openai` client reported it as a lost
    connection (its releases built on httpx wrap every error of a request so)."""
    cause = exc.__cause__
    return cause if isinstance(cause, AnswerDropped) else None


def _retry_after(exc: openai.APIStatusError) -> float:
    value = exc.response.headers.get("retry-after", "")
    try:
        return min(float(value), 300.0)
    except ValueError:
        return 0.0


def _say(exc: Exception) -> str:
    """One line for people: the status and the server's message when there is one, else
    the error and what caused it (`Connection refused`, a name that does not resolve)."""
    status = getattr(exc, "status_code", None)
    if isinstance(exc, openai.APIStatusError):
        text = error_message(exc) or str(exc)
    elif isinstance(exc, _Unreadable):
        text = str(exc)
    else:
        text = f"{type(exc).__name__}: {exc}"
        if exc.__cause__ is not None:
            text += f" ({exc.__cause__})"
    text = " ".join(text.split())[:300]
    return f"HTTP {status}: {text}" if status is not None else text


__all__ = ["MAX_RESPONSE_BYTES", "ChatClient", "ClientSettings", "Completion", "api_key"]
