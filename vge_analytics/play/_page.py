"""What the Play page does, apart from drawing: its state over Streamlit's session state, and
the texts it shows."""

from __future__ import annotations

from collections.abc import Mapping, MutableMapping, Sequence
from typing import Any, Literal

import replay
from replay.semantics import (
    ERROR,
    FEEDBACK_SEVERITY,
    INFO,
    LOG_ENDED,
    SUCCESS,
    TERMINATION_TEXTS,
    WARNING,
)

from .._errors import PlayConflictError, PlayError
from ._clicks import (
    CLICK_ACTIONS,
    DASHBOARD,
    PARAM_HINTS,
    SWITCH_VIEW,
    TIMED_WAIT,
    action,
    click_action,
    click_id,
    click_point,
)
from ._run import EpisodePlay, HumanRun, StepRecord, counted

Tone = Literal["success", "warning", "error"]
"""The Streamlit call (`st.success`, ...) that shows a message in a colour."""
_TONES: dict[str, Tone] = {INFO: "success", WARNING: "warning", ERROR: "error"}
FEEDBACK_TONES: dict[str, Tone] = {kind: _TONES[s] for kind, s in FEEDBACK_SEVERITY.items()}
"""How the page colours a step's feedback: by the kind's severity (PROTOCOL §3.6)."""


class PlayState:
    """What the Play page does, over its session state (any mutable mapping: Streamlit's
    `st.session_state`, a dict in tests). The page draws; every decision is here.

    Keys: `play_episode` (the picked episode, the picker's key), `play_game` (the episode
    being played, an `EpisodePlay`), `play_seen` (the last click acted on),
    `play_message` (a message for the next drawing of the page, shown once), and the keys of
    the page's widgets: the image's last click (`click_key`), the action a click does, its
    parameters (per action) and the view a `Switch_view` click goes to.
    """

    EPISODE = "play_episode"
    GAME = "play_game"
    SEEN = "play_seen"
    MESSAGE = "play_message"
    ACTION = "play_action"
    CLICK_VIEW = "play_click_view"
    VIEW = "play_view"

    def __init__(self, run: HumanRun, state: MutableMapping[str, Any]) -> None:
        self.run = run
        self.state = state

    # ------------------------------------------------------------------ reading

    def episode_id(self) -> str:
        """The picked episode; at first (or when it is not a task), the next one to play."""
        picked = self.state.get(self.EPISODE)
        if picked not in self.run.bench.tasks:
            picked = self.run.next_episode() or next(iter(self.run.bench.tasks), None)
            if picked is None:
                raise PlayError(f"{self.run.bench.tasks_path} has no episode")
            self.state[self.EPISODE] = picked
        return picked

    def game(self) -> EpisodePlay | None:
        """The episode being played, started when the picked one is new; None when it was
        played already or has unfinished steps (the page offers to resume or discard)."""
        episode_id = self.episode_id()
        game = self.state.get(self.GAME)
        if game is not None and game.episode_id == episode_id:
            return game
        self.state[self.GAME] = None  # another episode was picked: its journal stays
        if self.run.status(episode_id).state != "new":
            return None
        try:
            game = self.run.start(episode_id)
        except replay.VGEError as exc:
            self.say("error", str(exc))
            return None
        self.state[self.GAME] = game
        return game

    def message(self) -> tuple[str, str] | None:
        """(tone, text) to show once, then forgotten."""
        return self.state.pop(self.MESSAGE, None)

    def say(self, tone: str, text: str) -> None:
        self.state[self.MESSAGE] = (tone, text)

    # ------------------------------------------------------------------ acting

    def click_key(self) -> str:
        """Key of the image component: one per episode, so a new episode starts unclicked."""
        return f"play_click:{self.episode_id()}"

    @staticmethod
    def params_key(type_: str) -> str:
        return f"play_params:{type_}"

    def chosen_action(self) -> str:
        chosen = self.state.get(self.ACTION)
        return chosen if chosen in CLICK_ACTIONS else CLICK_ACTIONS[0]

    def click(self) -> None:
        """Carry out the chosen action at the image's last click, once per click (the image
        reports its last click again on every rerun of the page)."""
        click = self.state.get(self.click_key())
        seen = click_id(click)
        if seen is None or seen == self.state.get(self.SEEN):
            return
        self.state[self.SEEN] = seen
        type_ = self.chosen_action()
        params = self.state.get(self.params_key(type_), PARAM_HINTS.get(type_, ("",))[0])
        try:
            chosen = click_action(type_, click_point(click), params, self.click_view())
        except PlayError as exc:
            self.say("error", str(exc))
            return
        self.act(chosen)

    def click_view(self) -> str:
        """The view a `Switch_view` click goes to: as chosen, else the dashboard (what a
        click is needed for), else the first view."""
        game = self.state.get(self.GAME)
        views = list(game.observation["views"]) if game is not None else []
        chosen = self.state.get(self.CLICK_VIEW)
        if chosen in views or not views:
            return chosen or ""
        return DASHBOARD if DASHBOARD in views else views[0]

    def switch_view(self, view: str) -> None:
        self.act(action(SWITCH_VIEW, None, [view]))

    def wait(self) -> None:
        self.act(action(TIMED_WAIT))

    def act(self, chosen: Mapping[str, Any]) -> None:
        game = self.game()
        if game is None:
            return
        try:
            game.act(chosen)
        except replay.VGEError as exc:
            self.say("error", str(exc))
            if isinstance(exc, PlayConflictError) or game.broken:
                self.state[self.GAME] = None

    def give_up(self) -> None:
        """End the episode here (`log_ended`)."""
        game = self.game()
        if game is None:
            return
        try:
            if game.end() is None:
                self.say("info", "Nothing was played in this episode, so nothing was written.")
                self.state[self.GAME] = None
        except replay.VGEError as exc:
            self.say("error", str(exc))
            self.state[self.GAME] = None

    def resume(self) -> None:
        try:
            self.state[self.GAME] = self.run.resume(self.episode_id())
        except replay.VGEError as exc:
            self.say("error", str(exc))

    def discard(self) -> None:
        try:
            target = self.run.discard(self.episode_id())
        except replay.VGEError as exc:
            self.say("error", str(exc))
            return
        self.say("info", f"The unfinished steps were moved to {target}.")

    def pick_next(self) -> None:
        """Pick the next episode not played yet (after the picked one)."""
        following = self.run.next_episode(after=self.state.get(self.EPISODE))
        if following is None:
            self.say("info", "Every episode of the benchmark has been played in this run.")
            return
        self.state[self.EPISODE] = following


def click_hint(type_: str, view: str) -> str:
    """What a click on the image will do, in words."""
    if type_ == SWITCH_VIEW:
        return f"Click on it to switch to the {view} view with that point."
    return f"Click on it to {type_.lower()} there."


def goal_text(observation: Mapping[str, Any]) -> str:
    """`Goal 2 of 3: <instruction>` (the instruction of the current goal)."""
    index, total = int(observation["goal_index"]), int(observation["n_goals"])
    if index >= total:
        return f"All {total} goals completed."
    return f"Goal {index + 1} of {total}: {observation['instruction']}"


def budget_left(value: Any) -> str:
    """A budget as the page shows it (budgets are floats: λ may be fractional)."""
    return f"{float(value):g}"


def result_headline(termination: str) -> str:
    """How an episode that ended this way (PROTOCOL §3.5) reads: in Play the log ends when the
    player gives up; any other ending says why, in the words of `TERMINATION_TEXTS`."""
    if termination == SUCCESS:
        return "Success"
    if termination == LOG_ENDED:
        return "Ended by the player"
    ending = TERMINATION_TEXTS.get(termination)
    return f"Ended: {ending.reason}" if ending is not None else termination


def result_text(row: replay.EpisodeRow) -> str:
    """How an ended episode reads."""
    how = result_headline(row.termination)
    return (
        f"**{how}.** {row.goals_completed} of {counted(row.n_goals, 'goal')} completed in "
        f"{counted(row.L_act, 'step')} (the shortest way takes {row.L_opt}); SPL {row.spl:.2f}."
    )


def history(records: Sequence[StepRecord]) -> list[dict[str, Any]]:
    """The steps of the episode so far, newest first, for a table."""
    return [
        {"step": r.index, "action": r.action, "feedback": r.feedback} for r in reversed(records)
    ]


__all__ = [
    "FEEDBACK_TONES",
    "PlayState",
    "budget_left",
    "click_hint",
    "goal_text",
    "history",
    "result_headline",
    "result_text",
]
