"""An oracle of the planner (PROTOCOL §4): the fewest switches by plain recursion over every
option of every tight transition, and the optimal plan with §4.3's tie-breaks written out as
the protocol states them. Written apart from `replay.semantics._plan` (no shared code but
`progressing`, the tight transitions), for the tests that hold the planner to it."""

from __future__ import annotations

from replay.semantics import progressing

PREFERRED_VIEWS = (
    "front", "back", "left", "right", "top", "bottom", "dashboard", "front_top", "back_bottom"
)  # fmt: skip
"""PROTOCOL §4.3's order of views, as it reads there."""

NONE = 1 << 40


def _options(m, t, view: str, unlocked: bool) -> list[tuple]:
    """(switches, view after, unlocked after, the views switched to) of each way to take `t`."""
    if t.action is None:
        return [(0, view, unlocked, ())]
    regions = [v for v in PREFERRED_VIEWS if v in m.dashboard_regions]
    out = []
    for w in t.rects:
        if w in ("front_top", "back_bottom"):
            continue  # not interactable
        if w == view:
            out.append((0, w, unlocked, ()))
        elif w != "dashboard":
            out.append((1, w, unlocked, (w,)))
        elif unlocked or view in m.dashboard_regions:
            out.append((1, w, True, ("dashboard",)))
        elif regions:
            out.append((2, w, True, (regions[0], "dashboard")))
    return out


def _moves(m, goals, i: int, s: int, view: str, unlocked: bool) -> list[tuple]:
    """(transition, switches, view after, unlocked after, views switched to, goal index
    after) of every way to take a tight transition at a node."""
    moves = []
    for t in progressing(m, s, goals[i]):
        j = i
        for x in t.entered:
            if j < len(goals) and x == goals[j]:
                j += 1
        moves += [(t, *option, j) for option in _options(m, t, view, unlocked)]
    return moves


def oracle_switches(m, goals, i: int, s: int, view: str, unlocked: bool) -> int:
    """The fewest switches from a node on, by plain recursion over every option (each node
    worked out once: random machines of the hostile tests branch widely)."""
    memo: dict[tuple, int] = {}

    def fewest(i: int, s: int, view: str, unlocked: bool) -> int:
        key = (i, s, view, unlocked)
        if key not in memo:
            if i == len(goals):
                memo[key] = 0
            elif s == goals[i]:
                memo[key] = NONE
            else:
                memo[key] = min(
                    (
                        sw + fewest(j, t.end, v, u)
                        for t, sw, v, u, _, j in _moves(m, goals, i, s, view, unlocked)
                    ),
                    default=NONE,
                )
        return memo[key]

    return fewest(i, s, view, unlocked)


def oracle_plan(m, goals, s: int, view: str, unlocked: bool) -> list[tuple] | None:
    """(views switched to, transition) per step of the optimal plan, each step the optimal
    option least in (danger, switches now, view, component, file order); None if none."""
    if oracle_switches(m, goals, 0, s, view, unlocked) >= NONE:
        return None
    steps, i = [], 0
    while i < len(goals):
        best = oracle_switches(m, goals, i, s, view, unlocked)
        optimal = [
            move
            for move in _moves(m, goals, i, s, view, unlocked)
            if move[1] + oracle_switches(m, goals, move[5], move[0].end, move[2], move[3]) == best
        ]
        t, sw, v, u, pre, j = min(
            optimal,
            key=lambda mv: (
                mv[0].dangerous,
                mv[1],
                -1 if mv[0].action is None else PREFERRED_VIEWS.index(mv[2]),
                mv[0].component,
                mv[0].index,
            ),
        )
        steps.append((pre, (t.source, t.component, t.index)))
        i, s, view, unlocked = j, t.end, v, u
    return steps


def plan_steps(plan) -> list[tuple]:
    """A plan's steps as the oracle writes them."""
    steps, pre = [], []
    for step in plan.steps:
        if step.transition is None:
            pre.append(step.action.params[0])
        else:
            t = step.transition
            steps.append((tuple(pre), (t.source, t.component, t.index)))
            pre = []
    return steps


