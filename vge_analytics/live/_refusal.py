"""What an HTTP refusal of a model server means for `vge run` (PROTOCOL §10.3).

- `retry`: it may pass later: a server error (5xx), a rate limit (429), a request timeout
  (408) or a conflict (409).
- `context`: the request is longer than the model's context window. Retrying the same
  request cannot help and the next step's request would be longer still: the episode ends
  (`context_exceeded`, an outcome of the agent's settings).
- `key` (401, 403), `model` (404), `refused` (any other 4xx): every request would be refused
  alike, so the run stops.

Servers say "context window" in their own words; the ones recognised, each from the server's
own error paths:

- OpenAI: the error code `context_length_exceeded` ("This model's maximum context length is
  N tokens. However, your messages resulted in M tokens.").
- vLLM: no code of its own (`BadRequestError`, code 400), in one of the messages "This
  model's maximum context length is N tokens. However, your request has M input tokens.",
  "'max_tokens' or 'max_completion_tokens' is too large: K. This model's maximum context
  length is N tokens and your request has M input tokens" or "The decoder prompt (length M)
  is longer than the maximum model length of N."
- LiteLLM's proxy: the class of the error it mapped the provider's answer to, first in its
  message: "litellm.ContextWindowExceededError: ..." (its type and param null, its code "400").
- SGLang: "The input (M tokens) is longer than the model's context length (N tokens)."
"""

from __future__ import annotations

from typing import Literal

import openai

RETRIED_4XX = (408, 409, 429)
"""Client errors that may pass when sent again."""

CONTEXT_CODES = ("context_length_exceeded",)
CONTEXT_PHRASES = (
    "maximum context length",
    "longer than the maximum model length",
    "contextwindowexceedederror",
    "longer than the model's context length",
)
"""Lowercase; any of them in the error's message makes a context-length refusal."""

Refusal = Literal["retry", "context", "key", "model", "refused"]


def refusal(exc: openai.APIStatusError) -> Refusal:
    """What the refusal `exc` means (see the module docstring)."""
    status = exc.status_code
    if not 400 <= status < 500 or status in RETRIED_4XX:
        return "retry"
    if is_context_refusal(exc):
        return "context"
    if status in (401, 403):
        return "key"
    if status == 404:
        return "model"
    return "refused"


def is_context_refusal(exc: openai.APIStatusError) -> bool:
    """The server refused the request as longer than the model's context window."""
    if exc.code in CONTEXT_CODES:
        return True
    text = f"{exc.message} {error_message(exc)}".lower()
    return any(phrase in text for phrase in CONTEXT_PHRASES)


def error_message(exc: openai.APIStatusError) -> str:
    """The message of the server's error body (`{"error": {"message"}}` or, as older vLLM
    writes it, `{"object": "error", "message"}`), else ""."""
    body = exc.body
    message = body.get("message") if isinstance(body, dict) else None
    return message if isinstance(message, str) else ""


__all__ = ["RETRIED_4XX", "Refusal", "error_message", "is_context_refusal", "refusal"]
