"""The Episode viewer: episodes, steps and their classification in words.

A step's free texts (its thinking, action, feedback, the whole response) come cut at
`TEXT_CHARS` characters (`viewer_steps`), with their whole length beside them: a step whose
thinking held 10 MB never rendered. The page says what it cut (`long_texts`) and offers each
whole text as a download, read from the tables only when asked (`step_text`).
"""


from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import polars as pl

from replay.io import STEPS_TABLE
from replay.semantics import TERMINATION_TEXTS

from .._errors import UnknownColumnError, UnknownRunError
from ..reports import MISSING
from ..store import open_store, quote_ident, run_query, steps

TEXT_CHARS = 20_000
"""Characters of a step's free text the viewer shows; a longer one ends with `CUT`."""
CUT = " …"
"""What ends a text the viewer cut."""
LONG_TEXTS: dict[str, str] = {
    "thinking": "thinking",
    "action_raw": "action",
    "feedback_text": "feedback",
    "parse_detail": "parse detail",
    "output": "response",
}
"""The steps' free texts the viewer cuts (column -> what the page calls it)."""

_LABELS = {termination: ending.label for termination, ending in TERMINATION_TEXTS.items()}


def termination_label(termination: str) -> str:
    """How an episode ended, in words (`replay.semantics.TERMINATION_TEXTS`)."""
    return _LABELS.get(termination, termination)


def episode_labels(episodes: pl.DataFrame) -> dict[str, str]:
    """{episode_id: `<id> · <device> · <how it ended> · <done>/<goals> goals`} for a picker
    (computed once for all episodes: a full-scale run has 10^4 of them)."""
    ended = pl.col("termination").replace_strict(
        _LABELS, default=pl.col("termination"), return_dtype=pl.String
    )
    label = pl.format(
        "{} · {} · {} · {}/{} goals",
        "episode_id",
        "device_id",
        ended,
        "goals_completed",
        "n_goals",
    )
    return dict(episodes.select("episode_id", label.alias("label")).iter_rows())


def chars_column(field: str) -> str:
    """The column of `viewer_steps` that holds the whole length of the text `field`."""
    return f"{field}_chars"


def viewer_steps(out: str | Path, run_id: str, episode_id: str) -> pl.DataFrame:
    """Every step of one episode (truncated ones included), in log order, as the viewer shows
    them: each free text of `LONG_TEXTS` cut at `TEXT_CHARS` characters (and marked `CUT`),
    its whole length in `<field>_chars` (`chars_column`). The cut is made in the query, so
    the server holds no whole long text."""
    store = open_store(out)
    if run_id not in store.run_ids():
        raise UnknownRunError(f"unknown run {run_id!r} in {store.out}")
    texts = [quote_ident(f) for f in LONG_TEXTS]
    cut = ", ".join(
        f"CASE WHEN length({q}) > ? THEN left({q}, ?) || ? ELSE {q} END AS {q}" for q in texts
    )
    lengths = ", ".join(
        f"length({q}) AS {quote_ident(chars_column(f))}" for f, q in zip(LONG_TEXTS, texts, strict=True)
    )
    sql = (
        f"SELECT * REPLACE ({cut}), {lengths} FROM {STEPS_TABLE} "
        "WHERE run_id = ? AND episode_id = ? ORDER BY step"
    )
    return run_query(store, sql, [TEXT_CHARS, TEXT_CHARS, CUT] * len(texts) + [run_id, episode_id])


@dataclass(frozen=True)
class LongText:
    """A free text of a step the viewer shows cut."""

    field: str
    """Its column (a key of `LONG_TEXTS`)."""
    label: str
    chars: int
    """Its whole length, in characters."""

    @property
    def note(self) -> str:
        return (
            f"The {self.label} holds {self.chars:,} characters; the first {TEXT_CHARS:,} are "
            "shown. The button below downloads it whole."
        )


def long_texts(row: Mapping[str, object]) -> list[LongText]:
    """The free texts of a step of `viewer_steps` that were cut, in `LONG_TEXTS` order."""
    found = []
    for field, label in LONG_TEXTS.items():
        chars = row.get(chars_column(field))
        if isinstance(chars, int) and chars > TEXT_CHARS:
            found.append(LongText(field, label, chars))
    return found


def step_text(out: str | Path, run_id: str, episode_id: str, step: int, field: str) -> bytes:
    """The whole free text `field` (a key of `LONG_TEXTS`) of a step, as UTF-8: what the
    viewer's download gives, read from the tables when it is asked for."""
    if field not in LONG_TEXTS:
        raise UnknownColumnError(f"not a free text of a step: {field!r}; {', '.join(LONG_TEXTS)}")
    where = {"run_id": run_id, "episode_id": episode_id, "step": int(step)}
    rows = steps(out, where=where, columns=[field])
    if rows.height == 0:
        raise UnknownRunError(f"no step {step} in episode {episode_id!r} of run {run_id!r}")
    return (rows[field][0] or "").encode("utf-8")


def _code(text: object) -> str:
    """Inline code that survives any text (backticks inside are widened around), cut at
    `TEXT_CHARS` characters."""
    value = str(text).replace("\n", " ")
    if len(value) > TEXT_CHARS:
        value = value[:TEXT_CHARS] + CUT
    fence = "``" if "`" in value else "`"
    return f"{fence} {value} {fence}" if fence == "``" else f"`{value}`"


def step_caption(row: Mapping[str, object]) -> str:
    """Caption under the step picture: view, click, and what the colours mean."""
    click = (
        f"click ({row['x']:g}, {row['y']:g})"
        if row.get("x") is not None and row.get("y") is not None
        else "no click"
    )
    return (
        f"view {row['view_before']} · {click} · red x: click, green: target components, "
        "orange: components hit, grey: other components"
    )


def step_markdown(row: Mapping[str, object], goals: pl.DataFrame) -> str:
    """The step as the agent lived it: goal and instruction, action, feedback, state, view,
    budgets left (markdown; every free text in code spans)."""
    lines = [f"**Step {row['step']}**"]
    gi = row.get("goal_index")
    if gi is not None:
        goal = goals.filter(pl.col("goal_index") == gi)
        n = goals.height
        instruction = goal["instruction"][0] if goal.height else None
        lines.append(
            f"**Goal** {int(gi) + 1}/{n}: {_code(row['goal_state'])}"
            + (f" — {_code(instruction)}" if instruction else "")
        )
    lines.append(f"**Action** {_code(row['action_raw'])}")
    if not row.get("parse_ok"):
        lines.append(f"parse failure: {_code(row.get('parse_detail'))}")
    if row.get("truncated"):
        lines.append("*logged after the episode ended: not replayed, not scored*")
        return "  \n".join(lines)
    lines.append(f"**Feedback** ({row['feedback_kind']}) {_code(row['feedback_text'])}")
    entered = list(row.get("states_entered") or [])
    state = f"{_code(row['state_before'])} → {_code(row['state_after'])}"
    if len(entered) > 1:
        state += " via " + " → ".join(_code(s) for s in entered)
    if row.get("dangerous"):
        state += " · **dangerous** (entered an error state)"
    lines.append(f"**State** {state}")
    view = f"{row['view_before']} → {row['view_after']}"
    if row.get("dashboard_unlocked"):
        view += " · dashboard unlocked"
    lines.append(f"**View** {view}")
    lines.append(
        f"**Budgets left** global {row['budget_global_left']:g}, local {row['budget_local_left']:g}"
    )
    if row.get("diverged"):
        lines.append(f"**Diverged** from the log in {', '.join(row['diverged_fields'] or [])}")
    return "  \n".join(lines)


CLASSIFICATION_FIELDS: tuple[str, ...] = (
    "error_type",
    "error_detail",
    "error_group",
    "progress",
    "is_interaction",
    "hit_component",
    "hit_target",
    "hit_components",
    "nearest_target",
    "distance",
    "weight",
    "dist_before",
    "dist_after",
    "switch_class",
    "repetitive",
    "eer_valid",
    "completed_goals",
)
"""The step's classification (PROTOCOL §5) as the viewer lists it."""


def step_classification(row: Mapping[str, object]) -> pl.DataFrame:
    """The classification of a step as (field, value) rows, values as text (null as `reports.MISSING`)."""

    def text(value: object) -> str:
        if value is None:
            return MISSING
        if isinstance(value, float):
            return f"{value:.1f}"
        if isinstance(value, list):
            return ", ".join(map(str, value)) or MISSING
        return str(value)

    return pl.DataFrame(
        {
            "field": list(CLASSIFICATION_FIELDS),
            "value": [text(row.get(f)) for f in CLASSIFICATION_FIELDS],
        }
    )
