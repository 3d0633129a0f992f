"""The Side by side page: two runs on one common episode, step by step, each picture with the
planner's optimal next action (PROTOCOL §4.5) drawn on it, and the steps where the runs part
and first err marked."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import polars as pl

import replay

from .._errors import UnknownRunError
from ..reports import DIFF_COLUMNS, diff
from ..store import episodes, steps
from ._pictures import Box, device_machine, draw_step, view_boxes, view_picture


def pair_rows(out, run_a: str, run_b: str) -> pl.DataFrame:
    """`vge diff` of the two runs (one row per common episode) with each episode's device."""
    return diff(out, run_a, run_b).rows.select("episode_id", "device_id", *DIFF_COLUMNS[1:])


SIDE_STEP_COLUMNS: tuple[str, ...] = (
    "device_id",
    "step",
    "goal_index",
    "state_before",
    "view_before",
    "dashboard_unlocked",
    "action_raw",
    "x",
    "y",
    "hit_components",
    "progress",
    "error_type",
)
"""The step columns the page shows and plans from (not the model's text: a full run's
outputs would be read for nothing)."""


def side_steps(out, run_id: str, episode_id: str) -> pl.DataFrame:
    """Every logged step of a run's episode (`SIDE_STEP_COLUMNS`), in log order."""
    where = {"run_id": run_id, "episode_id": episode_id}
    return steps(out, where=where, columns=list(SIDE_STEP_COLUMNS))


def _solved(column: str) -> pl.Expr:
    return pl.when(pl.col(column)).then(pl.lit("solved")).otherwise(pl.lit("failed"))


def pair_labels(rows: pl.DataFrame) -> dict[str, str]:
    """{episode_id: `<id> · <device> · A solved · B failed · part at step 2`} for the episode
    picker (one vectorised expression: two full runs share 10^4 episodes)."""
    parted = (
        pl.when(pl.col("first_difference").is_null())
        .then(pl.lit("identical"))
        .otherwise(pl.format("part at step {}", "first_difference"))
    )
    label = pl.format(
        "{} · {} · A {} · B {} · {}",
        "episode_id",
        pl.col("device_id").fill_null("?"),
        _solved("success_a"),
        _solved("success_b"),
        parted,
    )
    return dict(rows.select("episode_id", label.alias("label")).iter_rows())


def default_episode(rows: pl.DataFrame) -> str:
    """The episode the page opens on: the first one the runs end differently (one solved
    it), else the first where they part, else the first (`rows` is not empty)."""
    rank = (
        pl.when(pl.col("success_a") != pl.col("success_b"))
        .then(0)
        .when(pl.col("first_difference").is_not_null())
        .then(1)
        .otherwise(2)
    )
    return str(rows.sort(rank, maintain_order=True)["episode_id"][0])


def step_marks(row: Mapping[str, object]) -> dict[int, list[str]]:
    """{step: what happens there} for the steps worth marking on the slider: the first
    difference, and each run's first error."""
    marks: dict[int, list[str]] = {}
    for column, text in (
        ("first_difference", "first difference"),
        ("first_error_a", "A's first error"),
        ("first_error_b", "B's first error"),
    ):
        step = row.get(column)
        if step is not None:
            marks.setdefault(int(step), []).append(text)  # type: ignore[arg-type]
    return marks


def step_label(step: int, marks: Mapping[int, Sequence[str]]) -> str:
    """How the slider names a step: its number, and its marks (`2 · first difference`)."""
    return " · ".join([str(step), *marks.get(step, ())])


def pair_summary(row: Mapping[str, object]) -> str:
    """One line under the pickers: where the runs part and where each first erred."""

    def at(value: object, none: str) -> str:
        return none if value is None else f"step {value}"

    return (
        f"**First difference** {at(row['first_difference'], 'none: identical replays')} · "
        f"**A's first error** {at(row['first_error_a'], 'none')} · "
        f"**B's first error** {at(row['first_error_b'], 'none')} · "
        f"steps A {row['steps_a']}, B {row['steps_b']}"
    )


def side_heading(name: str, run: str, step: int, n_steps: int) -> str:
    """The line above a run's picture at `step` of the shared slider, its log holding
    `n_steps` steps (numbered from 0): `**B · run** · step 2 of steps 0–4`, or, past its
    end, `**B · run** · its log ended at step 1` (the other run's log goes on)."""
    head = f"**{name} · {run}**"
    if n_steps == 0:
        return f"{head} · its log has no step"
    if step >= n_steps:
        return f"{head} · its log ended at step {n_steps - 1}"
    if n_steps == 1:
        return f"{head} · step 0, its only step"
    return f"{head} · step {step} of steps 0–{n_steps - 1}"


def ended_note(name: str, step: int, n_steps: int) -> str | None:
    """What stands in place of a run's picture at a step past the end of its log (None:
    the step is in its log)."""
    if step < n_steps:
        return None
    if n_steps == 0:
        return f"{name}'s log of this episode has no step."
    return (
        f"{name}'s log ended at step {n_steps - 1}: no step {step} to show "
        f"(the slider follows the longer log)."
    )


@dataclass(frozen=True)
class OptimalStep:
    """The planner's next action from a step's situation (PROTOCOL §4.5)."""

    action: str
    """The action as text, e.g. `Push(coord=[480, 90], params=[1])`."""
    component: str | None
    """The component it acts on; None for a switch or a wait."""
    boxes: tuple[Box, ...]
    """That component's boxes in the current view (role `optimal`); none for a switch or a
    wait."""


def optimal_next_step(
    machine: replay.Machine, episode: pl.DataFrame, goals: Sequence[str], step: int
) -> OptimalStep | None:
    """The optimal next action at the situation before `step` of an episode (its steps in log
    order): that step's state and view before, the dashboard as the step before left it
    (locked at reset), and the goals from that step's current goal on. None when the step
    was not replayed (truncated) or no plan reaches the remaining goals from there."""
    row = episode.row(step, named=True)
    if row["goal_index"] is None:
        return None
    unlocked = bool(episode["dashboard_unlocked"][step - 1]) if step > 0 else False
    remaining = tuple(machine.state_id(g) for g in goals[row["goal_index"] :])
    view = row["view_before"]
    planned = replay.next_optimal_step(
        machine, machine.state_id(row["state_before"]), view, unlocked, remaining
    )
    if planned is None:
        return None
    transition = planned.transition
    if transition is None or transition.action is None:  # a switch, or a wait
        return OptimalStep(planned.action.to_text(), None, ())
    boxes = tuple(
        Box(transition.component, *rect[:4], role="optimal")
        for rect in transition.rects.get(view, ())
    )
    return OptimalStep(planned.action.to_text(), transition.component, boxes)


@dataclass(frozen=True)
class SidePicture:
    """One run's picture of a step and the optimal action drawn on it."""

    png: bytes
    optimal: OptimalStep | None


def side_picture(out, run_id: str, episode_id: str, step: int) -> SidePicture:
    """The view a run saw before `step`, with the components (grey), those the click hit
    (orange), the click (red x) and the box of the planner's optimal next action (blue)."""
    episode = side_steps(out, run_id, episode_id)
    if not 0 <= step < episode.height or episode["view_before"][step] is None:
        raise UnknownRunError(f"no replayed step {step} in episode {episode_id!r} of {run_id!r}")
    row = episode.row(step, named=True)
    task = episodes(out, where={"run_id": run_id, "episode_id": episode_id}, columns=["goals"])
    machine = device_machine(out, row["device_id"], run_id)
    optimal = optimal_next_step(machine, episode, task["goals"][0].to_list(), step)
    view = row["view_before"]
    boxes = view_boxes(machine, view, hit=list(row["hit_components"] or []), targets=[])
    boxes += list(optimal.boxes if optimal else ())  # drawn last, on top
    click = (row["x"], row["y"]) if row["x"] is not None and row["y"] is not None else None
    picture = view_picture(out, row["device_id"], view, run_id)
    return SidePicture(draw_step(picture, boxes, click), optimal)


def side_caption(row: Mapping[str, object], optimal: OptimalStep | None) -> str:
    """Caption under a run's picture: the action taken, its verdict, the optimal action."""
    verdict = row.get("error_type") or ("progress" if row.get("progress") else "no error")
    if optimal is None:
        best = "no optimal next step from here"
    elif optimal.component is None:
        best = f"optimal: {optimal.action}"
    else:
        best = f"optimal (blue): {optimal.action} on {optimal.component}"
    return f"view {row['view_before']} · {row['action_raw']} → {verdict} · {best}"


__all__ = [
    "OptimalStep",
    "SidePicture",
    "default_episode",
    "ended_note",
    "optimal_next_step",
    "pair_labels",
    "pair_rows",
    "pair_summary",
    "side_caption",
    "side_heading",
    "side_picture",
    "side_steps",
    "SIDE_STEP_COLUMNS",
    "step_label",
    "step_marks",
]
