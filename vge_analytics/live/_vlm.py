"""`openai:MODEL`: a vision-language model behind an OpenAI-compatible chat API, prompted
ReAct-style (`_prompt.py`) with the current view as a PNG and the last K steps of the
conversation (`--history K`), the latest J of them with their pictures (`--history-images J`;
by default every step kept keeps its picture, as in a chat that shows the whole history)."""

from __future__ import annotations

import threading
from typing import Any

import replay

from ._agents import AgentOptions, EpisodeStart, Reply, history_text
from ._openai import ChatClient
from ._prompt import Turn, build_messages, observation_text, png_data_url


class OpenAIAgent:
    looks = True
    agent_kind = "vlm"

    def __init__(self, model: str, options: AgentOptions, client: ChatClient | None = None) -> None:
        self.spec = f"openai:{model}"
        self.model = model
        self.history = options.history
        self.history_images = options.history_images
        self.client_settings = options.client
        self.client = client if client is not None else ChatClient(model, options.client)

    def settings(self) -> dict[str, Any]:
        s = self.client_settings
        out: dict[str, Any] = {
            "agent": self.spec,
            "history_length": history_text(self.history),
            "history_images": history_text(self.history_images),
            "base_url": s.base_url or "",
            "request_timeout_seconds": s.timeout,
            "max_response_bytes": s.max_response_bytes,
            "retries": s.retries,
        }
        if s.temperature is not None:
            out["temperature"] = s.temperature
        if s.max_tokens is not None:
            out["max_tokens"] = s.max_tokens
        return out

    def check(self) -> None:
        """The server answers, takes the key and knows the model (`ChatClient.check`)."""
        self.client.check()

    def start(self, episode: EpisodeStart) -> _VLMPlayer:
        return _VLMPlayer(self.client, self.history, self.history_images, episode.stop)


class _VLMPlayer:
    def __init__(
        self,
        client: ChatClient,
        history: int | None,
        images: int | None,
        stop: threading.Event | None,
    ) -> None:
        self.client = client
        self.history = history
        self.images = images
        self.stop = stop
        self.turns: list[Turn] = []
        self.last_action: str | None = None
        self._pending: Turn | None = None

    def act(self, obs: dict[str, Any]) -> Reply:
        said = observation_text(obs, self.last_action)
        if self.history is None:
            kept = self.turns
        else:
            kept = self.turns[len(self.turns) - self.history :] if self.history else []
        picture = png_data_url(obs["image"])
        answer = self.client.complete(
            build_messages(kept, said, picture, images=self.images), stop=self.stop
        )
        self._pending = Turn(said, picture, answer.text)
        return Reply(
            answer.text,
            prompt_tokens=answer.prompt_tokens,
            completion_tokens=answer.completion_tokens,
            latency_seconds=round(answer.latency_seconds, 3),
            timestamp=round(answer.timestamp, 3),
        )

    def recall(
        self,
        obs: dict[str, Any],
        step: replay.LogStep,
        after: dict[str, Any],
        info: dict[str, Any],
    ) -> None:
        """A step before the cut of a continuation run (the source's, or the fix), told as
        the model's own answer: the turn `act` and `observe` would have made of it, so the
        conversation at the cut is the one the model would have had."""
        said = observation_text(obs, self.last_action)
        answered = step.output
        if answered is None:  # a structured action (a human's, or the fix) as a call
            answered = f"Action: {replay.semantics.parse_log_step(step).action_text}"
        self._pending = Turn(said, png_data_url(obs["image"]), answered)
        self.observe(after, info)

    def observe(self, obs: dict[str, Any], info: dict[str, Any]) -> None:
        assert self._pending is not None
        self.turns.append(self._pending)
        # What the model is told it did: the call it wrote, as the grammar read it.
        self.last_action = replay.parse_action(self._pending.answered).action_text
        self._pending = None


__all__ = ["OpenAIAgent"]
