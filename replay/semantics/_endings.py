"""How the end of an episode reads to a person, one entry per termination (PROTOCOL §3.5):
the dashboard's labels, the export's and the Play page's sentences."""

from __future__ import annotations

from dataclasses import dataclass

from ._vocab import BUDGET_GLOBAL, BUDGET_LOCAL, CONTEXT_EXCEEDED, LOG_ENDED, SUCCESS


@dataclass(frozen=True)
class Ending:
    """The words for one termination."""

    label: str
    """A few words for a table or a picker (`global budget out`)."""
    reason: str
    """Why the episode is over, as a clause (`the episode's step budget is spent`)."""


TERMINATION_TEXTS: dict[str, Ending] = {
    SUCCESS: Ending("success", "every goal is reached"),
    BUDGET_GLOBAL: Ending("global budget out", "the episode's step budget is spent"),
    BUDGET_LOCAL: Ending("local budget out", "the step budget of the current goal is spent"),
    LOG_ENDED: Ending("log ended", "the log ends here"),
    CONTEXT_EXCEEDED: Ending("context window full", "the model's context window is full"),
}
"""The words of each termination, in `TERMINATIONS` order (a new termination is one line here
and one in `TERMINATIONS`; a test checks that the keys match)."""

__all__ = ["TERMINATION_TEXTS", "Ending"]
