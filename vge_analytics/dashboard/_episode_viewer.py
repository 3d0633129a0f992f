"""The Episode viewer: episodes, steps and their classification in words."""


from __future__ import annotations

from collections.abc import Mapping

import polars as pl

from replay.semantics import TERMINATION_TEXTS

from ..reports import MISSING

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


def _code(text: object) -> str:
    """Inline code that survives any text (backticks inside are widened around)."""
    value = str(text).replace("\n", " ")
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
