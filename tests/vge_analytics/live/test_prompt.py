"""The prompt of `openai:` agents: its examples are actions the grammar reads, the step message
says what the model needs, `--history K` keeps the last K turns and `--history-images J` the
pictures of the latest J of them."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

import replay
from replay.env import DeviceEnv, no_images
from vge_analytics.live import SYSTEM_PROMPT, AgentOptions, Completion, EpisodeStart
from vge_analytics.live._vlm import OpenAIAgent

from .conftest import MALFORMED, PUSH_POWER, WAIT


def test_every_example_of_the_prompt_is_a_valid_action() -> None:
    section = SYSTEM_PROMPT.split("## 6. Examples")[1]
    examples = re.findall(r"^Thinking: .*\nAction: .*$", section, flags=re.MULTILINE)
    assert len(examples) == 4
    parsed = [replay.parse_action(text) for text in examples]
    assert all(p.ok for p in parsed)
    assert [p.action.type for p in parsed] == ["rotate", "switch_view", "timed_wait", "switch_view"]
    # Every action of the grammar is described, by the name the grammar reads.
    for name in ("Press", "Rotate", "Push", "Pull", "Grasp", "Switch_view", "Timed_wait"):
        assert f"- {name}(" in SYSTEM_PROMPT


class _Recorder:
    """Stands in for the chat client: answers from a list, keeps what it was sent."""

    def __init__(self, answers: list[str]) -> None:
        self.answers = list(answers)
        self.sent: list[list[dict]] = []

    def complete(self, messages: list[dict], *, stop: object = None) -> Completion:
        self.sent.append(messages)
        return Completion(self.answers.pop(0), 10, 2, 0.5, 1.8e9)


@pytest.mark.parametrize(("history", "kept"), [(None, [0, 1, 2]), (0, [0, 0, 0]), (1, [0, 1, 1])])
def test_history_keeps_the_last_k_turns(
    kettle_bench: Path, history: int | None, kept: list[int]
) -> None:
    recorder = _Recorder([MALFORMED, PUSH_POWER, WAIT])
    agent = OpenAIAgent("m", AgentOptions(history=history), client=recorder)  # type: ignore[arg-type]
    env = DeviceEnv(kettle_bench, image_source=no_images, image_width=16, image_height=12)
    obs, _ = env.reset(options={"episode_id": "boil"})
    player = agent.start(EpisodeStart(obs, env, "r"))
    done = False
    while not done:
        reply = player.act(obs)
        assert (reply.prompt_tokens, reply.completion_tokens, reply.latency_seconds) == (10, 2, 0.5)
        obs, _, terminated, truncated, info = env.step(reply.action)
        player.observe(obs, info)
        done = terminated or truncated
    assert [(len(m) - 2) // 2 for m in recorder.sent] == kept
    first, second, third = (m[-1]["content"][0]["text"] for m in recorder.sent)
    assert first.splitlines() == [
        "Request: Boil the water.",
        "Current view: front",
        "Views of this device: front, back, left, right, top, bottom, front_top, back_bottom",
        "This is your first action.",
    ]
    assert "Your last action: Push(coord=[480, 90, params=[1])" in second  # as it was written
    assert "What happened: System Notification:" in second
    assert "Your last action: Push(coord=[780, 725], params=[1])" in third
    assert recorder.sent[-1][-1]["content"][1]["image_url"]["url"].startswith("data:image/png")


def _play_boil(kettle_bench: Path, options: AgentOptions) -> list[list[dict]]:
    """The requests of an `openai:` agent over the kettle's `boil` episode (three steps)."""
    recorder = _Recorder([MALFORMED, PUSH_POWER, WAIT])
    agent = OpenAIAgent("m", options, client=recorder)  # type: ignore[arg-type]
    env = DeviceEnv(kettle_bench, image_source=no_images, image_width=16, image_height=12)
    obs, _ = env.reset(options={"episode_id": "boil"})
    player = agent.start(EpisodeStart(obs, env, "r"))
    done = False
    while not done:
        obs, _, terminated, truncated, info = env.step(player.act(obs).action)
        player.observe(obs, info)
        done = terminated or truncated
    return recorder.sent


@pytest.mark.parametrize(
    ("history", "images", "pictured"),
    [
        (None, None, [True, True]),  # the whole conversation, as a chat shows it
        (None, 1, [False, True]),
        (None, 0, [False, False]),
        (1, None, [True]),
        (1, 0, [False]),
        (2, 5, [True, True]),
    ],
)
def test_history_images_keeps_the_pictures_of_the_latest_j_turns(
    kettle_bench: Path, history: int | None, images: int | None, pictured: list[bool]
) -> None:
    sent = _play_boil(kettle_bench, AgentOptions(history=history, history_images=images))
    # The current step always has its picture; past user messages have one or are text.
    current_pictures = [m[-1]["content"][1]["image_url"]["url"] for m in sent]
    third = sent[2]
    past_users = [m for m in third[1:-1] if m["role"] == "user"]
    assert [isinstance(m["content"], list) for m in past_users] == pictured
    # A past turn's picture is the one it was sent with; its text is the same either way.
    first_kept = 2 - len(past_users)
    for k, message in enumerate(past_users):
        said = sent[first_kept + k][-1]["content"][0]["text"]
        if isinstance(message["content"], list):
            assert message["content"][0]["text"] == said
            assert message["content"][1]["image_url"]["url"] == current_pictures[first_kept + k]
        else:
            assert message["content"] == said


def test_history_images_is_a_setting_of_the_run() -> None:
    agent = OpenAIAgent("m", AgentOptions(history_images=2), client=_Recorder([]))  # type: ignore[arg-type]
    assert agent.settings()["history_images"] == "2"
    agent = OpenAIAgent("m", AgentOptions(), client=_Recorder([]))  # type: ignore[arg-type]
    assert agent.settings()["history_images"] == "unlimited"


def test_a_locked_dashboard_is_listed_as_locked() -> None:
    from vge_analytics.live._prompt import views_text

    obs = {"views": ("front", "dashboard"), "dashboard_unlocked": 0}
    assert views_text(obs) == "front, dashboard (locked)"
    assert views_text({**obs, "dashboard_unlocked": 1}) == "front, dashboard"
