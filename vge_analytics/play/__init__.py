"""Playing a benchmark by hand: the click mapping and the human run behind the Play page.

`vge play BENCH --out RUN` serves the Play page (`app/views/play.py`), which is a thin layer
over this module. The game is `replay.env.DeviceEnv` (`vge/Device-v0`), itself a wrapper
over `replay.EpisodeSession`, the object the replay drives: a played episode and the replay
of its log cannot disagree.

The run directory is one `vge replay` reads (PROTOCOL §1.4):

    RUN/run.json                  agent_kind "human", written when the run is created
    RUN/episodes.jsonl            one line per finished episode, structured actions
    RUN/playing/<episode>.jsonl   the journal of an episode being played (not read by replay)
    RUN/playing/discarded/        journals a person chose to throw away, torn lines cut off
                                  the episodes file (kept, never read)

Crash safety. Each step is appended to the episode's journal (one `write`, then `fsync`)
before the page shows its feedback, so a step a person has seen is on disk. When the episode
ends, its whole line is appended to `episodes.jsonl` the same way, and only then is the
journal removed. If the app dies:
- mid-step: the journal's last line may be torn; it is cut off when the episode is resumed
  (that step's feedback was never shown);
- mid-episode: the journal stays; the page offers to resume the episode (its steps are
  played again through the environment, which must give the feedback, state and view the
  journal recorded) or to discard it (the journal is moved to `playing/discarded/`);
- while ending an episode: a torn last line of `episodes.jsonl` is cut off when the run is
  opened (the journal, still there, holds the same steps; the torn bytes are kept in
  `playing/discarded/`), and a journal whose episode line is complete is removed.

Several browser tabs may play the same run: writes take a lock on the run, and a journal
that changed since a tab last wrote to it (another tab played on) is refused with a message
rather than interleaved.
"""

from typing import TYPE_CHECKING

from replay import lazy_names

if TYPE_CHECKING:  # the names, imported when first used (`lazy_names`)
    from ._clicks import (
        CLICK_ACTIONS,
        DASHBOARD,
        INTERACTIONS,
        PARAM_HINTS,
        SCALE,
        SWITCH_VIEW,
        TIMED_WAIT,
        action,
        action_text,
        click_action,
        click_id,
        click_point,
        parse_params,
        scale_coordinate,
    )
    from ._files import DEFAULT_RUN_DIR
    from ._page import (
        FEEDBACK_TONES,
        PlayState,
        budget_left,
        click_hint,
        goal_text,
        history,
        result_headline,
        result_text,
    )
    from ._run import (
        DEFAULT_MODEL,
        IMAGE_SIZE,
        EpisodePlay,
        EpisodeStatus,
        HumanRun,
        StepRecord,
    )

__all__ = [
    "CLICK_ACTIONS",
    "DASHBOARD",
    "DEFAULT_MODEL",
    "DEFAULT_RUN_DIR",
    "FEEDBACK_TONES",
    "IMAGE_SIZE",
    "INTERACTIONS",
    "PARAM_HINTS",
    "SCALE",
    "SWITCH_VIEW",
    "TIMED_WAIT",
    "EpisodePlay",
    "EpisodeStatus",
    "HumanRun",
    "PlayState",
    "StepRecord",
    "action",
    "action_text",
    "budget_left",
    "click_action",
    "click_hint",
    "click_id",
    "click_point",
    "goal_text",
    "history",
    "parse_params",
    "result_headline",
    "result_text",
    "scale_coordinate",
]

__getattr__, __dir__ = lazy_names(__name__, __file__)
