"""Episode sampling (paper, "Instruction Generation"): goal sequences found by walking valid
transition paths from the initial state, phrased with the catalog's goal phrases.

Single-turn tasks have one goal; multi-turn ones 2-4 goals, each reachable from where the
previous one leaves the device, with no goal repeated (returning to the initial state is
allowed only as the last goal). Every task is checked with `replay.semantics.setup_episode` (so it is
plannable) and carries the planner's `c_opt`. Instructions never name a component: they are
the catalog's phrases, with light connectives between the goals of a multi-turn task.
"""

from __future__ import annotations

import random
from dataclasses import dataclass

import replay
from replay.semantics import BACK, FRONT, FRONT_TOP, LEFT, RIGHT, TOP

from ._catalog import Catalog, load_catalog

INF = 1 << 30
_DISTANCE_WEIGHT = {1: 1.0, 2: 0.45, 3: 0.15}
_GOAL_COUNTS = ((2, 0.58), (3, 0.3), (4, 0.12))
_CONNECTIVES = ("Then", "Next,", "Now", "After that,", "Once that's done,", "When that's done,")
_LAST_CONNECTIVES = ("Finally,", "Lastly,", "To finish,")
_OTHER_START_VIEWS = (BACK, LEFT, RIGHT, TOP)


@dataclass(frozen=True, slots=True)
class TaskRecord:
    """One line of `tasks.jsonl` (PROTOCOL §1.3)."""

    episode_id: str
    device_id: str
    goals: tuple[str, ...]
    instructions: tuple[str, ...]
    initial_view: str
    c_opt: tuple[int, ...]

    def to_json(self) -> dict:
        return {
            "episode_id": self.episode_id,
            "device_id": self.device_id,
            "goals": list(self.goals),
            "instructions": list(self.instructions),
            "initial_view": self.initial_view,
            "c_opt": list(self.c_opt),
        }

    def to_task(self) -> replay.Task:
        return replay.Task(
            episode_id=self.episode_id,
            device_id=self.device_id,
            goals=list(self.goals),
            instructions=list(self.instructions),
            initial_view=self.initial_view,
            c_opt=list(self.c_opt),
        )


def goal_candidates(machine: replay.Machine, catalog: Catalog) -> tuple[int, ...]:
    """States that can be goals: phrased in the catalog, not error states."""
    return tuple(
        i
        for i, name in enumerate(machine.states)
        if name in catalog.goal_phrases and i not in machine.error_states
    )


def _pick_goal(
    machine: replay.Machine,
    start: int,
    candidates: tuple[int, ...],
    exclude: set[int],
    rng: random.Random,
) -> int | None:
    options: list[tuple[int, float]] = []
    for g in candidates:
        if g == start or g in exclude:
            continue
        d = replay.semantics.distances(machine, g)[start]
        w = _DISTANCE_WEIGHT.get(d, 0.0) if d < INF else 0.0
        if w > 0:
            options.append((g, w))
    if not options:
        return None
    total = sum(w for _, w in options)
    x = rng.random() * total
    for g, w in options:
        x -= w
        if x <= 0:
            return g
    return options[-1][0]


def sample_goals(
    machine: replay.Machine, catalog: Catalog, n_goals: int, rng: random.Random
) -> tuple[int, ...] | None:
    """A loop-free goal sequence of length `n_goals` from the device's initial state."""
    candidates = goal_candidates(machine, catalog)
    start0 = machine.chain_end[machine.initial]
    for _ in range(12):
        goals: list[int] = []
        used: set[int] = set()
        s = start0
        ok = True
        for k in range(n_goals):
            last = k == n_goals - 1
            exclude = set(used)
            if not last:
                exclude.add(start0)
            g = _pick_goal(machine, s, candidates, exclude, rng)
            if g is None:
                ok = False
                break
            goals.append(g)
            used.add(g)
            s = machine.chain_end[g]
        if ok:
            return tuple(goals)
    return None


def _initial_view(rng: random.Random) -> str:
    x = rng.random()
    if x < 0.78:
        return FRONT
    if x < 0.9:
        return rng.choice(_OTHER_START_VIEWS)
    return FRONT_TOP


def _lower_first(text: str) -> str:
    if len(text) > 1 and text[0].isupper() and not text[1].isupper():
        return text[0].lower() + text[1:]
    return text


def phrase_goals(
    machine: replay.Machine, catalog: Catalog, goals: tuple[int, ...], rng: random.Random
) -> tuple[str, ...]:
    """One instruction per goal, from the goal phrases, with connectives for multi-turn."""
    out: list[str] = []
    for i, g in enumerate(goals):
        text = rng.choice(catalog.goal_phrases[machine.states[g]])
        if i > 0:
            x = rng.random()
            if i == len(goals) - 1 and len(goals) > 2 and x < 0.35:
                text = f"{rng.choice(_LAST_CONNECTIVES)} {_lower_first(text)}"
            elif x < 0.55:
                text = f"{rng.choice(_CONNECTIVES)} {_lower_first(text)}"
        elif rng.random() < 0.12:
            text = f"Please {_lower_first(text)}"
        if not text.endswith((".", "!", "?")) and rng.random() < 0.3:
            text += "."
        out.append(text)
    return tuple(out)


def sample_tasks(
    machine: replay.Machine,
    category: str,
    n_single: int,
    n_multi: int,
    rng: random.Random,
) -> list[TaskRecord]:
    """`n_single` single-turn then `n_multi` multi-turn tasks for one device, all plannable.

    Distinct (goals, initial view) pairs are preferred; when a small device runs out of them
    a pair may repeat with other wording (the paper's devices have 15 tasks on average)."""
    catalog = load_catalog(category)
    device_id = machine.device_id
    out: list[TaskRecord] = []
    seen: set[tuple] = set()
    plan_n = [1] * n_single + [_draw_goal_count(rng) for _ in range(n_multi)]
    for k, n_goals in enumerate(plan_n):
        record = None
        for attempt in range(40):
            goals = sample_goals(machine, catalog, n_goals, rng)
            if goals is None:
                if n_goals > 2:
                    n_goals -= 1
                continue
            view = _initial_view(rng)
            key = (goals, view)
            if key in seen and attempt < 30:
                continue
            instructions = phrase_goals(machine, catalog, goals, rng)
            task = replay.Task(
                episode_id=f"{device_id}-{k:02d}",
                device_id=device_id,
                goals=[machine.states[g] for g in goals],
                instructions=list(instructions),
                initial_view=view,
            )
            try:
                setup = replay.semantics.setup_episode(machine, task)
            except replay.TaskError:
                continue
            seen.add(key)
            record = TaskRecord(
                task.episode_id,
                device_id,
                tuple(task.goals),
                instructions,
                view,
                tuple(setup.plan.c_opt),
            )
            break
        if record is None:
            raise RuntimeError(f"{device_id}: no plannable {n_goals}-goal task")
        out.append(record)
    return out


def _draw_goal_count(rng: random.Random) -> int:
    x = rng.random()
    for n, p in _GOAL_COUNTS:
        x -= p
        if x <= 0:
            return n
    return _GOAL_COUNTS[-1][0]
