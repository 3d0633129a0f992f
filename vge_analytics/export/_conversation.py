"""An episode as the conversation the agent had: what it was shown, what it answered.

The replay keeps each step's response and the feedback the environment gave; the prompt
around them is rebuilt with the words of our own harness (`vge_analytics.live`: its system
message, and the user message of each step, `observation_text`), so an exported episode
reads as the conversation an agent run by `vge run` has, step for step: the request, the
view it looks at (its picture beside the text), the views it can switch to, its last action
and what happened. Logs of other harnesses get the same wording: their prompts are not in
the logs.

After the step that ends the episode, the agent is told what happened and why the episode
is over. Responses the log holds after that (truncated steps, PROTOCOL §3.5) are kept as
answers without a reply: the replay did not play them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from replay.semantics import TERMINATION_TEXTS
from vge_analytics.live import SYSTEM_PROMPT, observation_text

from ._source import Episode


@dataclass(frozen=True)
class Said:
    """What the agent was shown: a text, and the view whose picture went with it."""

    text: str
    view: str | None


@dataclass(frozen=True)
class Exchange:
    """One step: the agent's response, and what the environment answered."""

    step: dict[str, Any]
    """The step's row (PROTOCOL §7.2)."""
    answer: str
    """The response as logged: the model's text, or the structured action."""
    reply: Said | None
    """None for a step logged after the episode ended (not played)."""


@dataclass(frozen=True)
class Conversation:
    system: str
    opening: Said
    exchanges: list[Exchange]


def answer_of(step: dict[str, Any]) -> str:
    return step["output"] if step["output"] is not None else step["action_raw"]


def _observation(
    episode: Episode, views: tuple[str, ...], step: dict[str, Any], before: dict[str, Any] | None
) -> dict[str, Any]:
    """The observation the agent had when it took `step` (`before`: the step before it), in
    the shape `observation_text` reads."""
    goal = step["goal_index"]
    instructions = episode.instructions
    return {
        "instruction": instructions[goal] if goal is not None and goal < len(instructions) else "",
        "n_goals": episode.row["n_goals"],
        "goal_index": goal or 0,
        "view": step["view_before"],
        "views": views,
        "dashboard_unlocked": bool(before and before["dashboard_unlocked"]),
        "feedback": before["feedback_text"] if before else "",
    }


def _ending(episode: Episode, last: dict[str, Any], truncated: int) -> Said:
    termination = episode.row["termination"]
    ending = TERMINATION_TEXTS.get(termination)
    why = ending.reason if ending is not None else termination
    text = (
        f"Your last action: {last['action_raw'] or '(it could not be read)'}\n"
        f"What happened: {last['feedback_text']}\n"
        f"The episode is over: {why}."
    )
    if truncated:
        text += f" (The log holds {truncated} more response(s), which the replay does not play.)"
    return Said(text, last["view_after"])


def conversation(episode: Episode, views: tuple[str, ...]) -> Conversation:
    """The episode's conversation; `views`: the views of its device."""
    steps = episode.steps
    played = [s for s in steps if not s["truncated"]]
    if played:
        opening = Said(
            observation_text(_observation(episode, views, played[0], None), None),
            played[0]["view_before"],
        )
    else:  # an empty log: the agent was shown the first request and never answered
        first = {"goal_index": 0, "view_before": episode.row["initial_view"]}
        opening = Said(
            observation_text(_observation(episode, views, first, None), None),
            episode.row["initial_view"],
        )
    exchanges: list[Exchange] = []
    for i, step in enumerate(played):
        if i + 1 < len(played):
            after = played[i + 1]
            reply = Said(
                observation_text(_observation(episode, views, after, step), step["action_raw"]),
                after["view_before"],
            )
        else:
            reply = _ending(episode, step, len(steps) - len(played))
        exchanges.append(Exchange(step, answer_of(step), reply))
    exchanges += [Exchange(s, answer_of(s), None) for s in steps if s["truncated"]]
    return Conversation(SYSTEM_PROMPT, opening, exchanges)


__all__ = ["Conversation", "Exchange", "Said", "answer_of", "conversation"]
