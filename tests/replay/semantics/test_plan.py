"""Planner (PROTOCOL §4): distances, target components, C_opt with its tie-breaks, C_opt_dyn."""

from __future__ import annotations

from pathlib import Path

import msgspec
import pytest

from replay import Task, TaskError, load_machine, next_optimal_step
from replay.semantics import (
    c_opt_dynamic,
    distances,
    plan_goals,
    setup_episode,
    target_components,
)

from ..machines import box, machine, tr
from ..plan_oracle import oracle_plan, plan_steps

KETTLE = load_machine(Path(__file__).resolve().parents[2] / "data" / "kettle_ssm.json", "kettle")


def _s(name: str) -> int:
    return KETTLE.state_id(name)


def test_kettle_distances_count_immediate_edges_as_free() -> None:
    to_boiling = distances(KETTLE, _s("Boiling"))
    assert to_boiling[_s("Standby")] == 1
    assert to_boiling[_s("LidOpen")] == 2  # close the lid (or the dangerous shortcut), then power
    assert to_boiling[_s("Error")] == 1  # Error resets to Standby at no cost
    to_complete = distances(KETTLE, _s("BoilingComplete"))
    assert to_complete[_s("Standby")] == 2
    assert to_complete[_s("Boiling")] == 1  # by waiting
    assert distances(KETTLE, _s("Standby"))[_s("Boiling")] == 1


def test_kettle_target_components() -> None:
    assert target_components(KETTLE, _s("Standby"), _s("Boiling")) == {"power_button"}
    assert (
        target_components(KETTLE, _s("Boiling"), _s("BoilingComplete")) == frozenset()
    )  # waiting only
    # Both Boiling exits end in Standby (the lid one through Error), so both are targets.
    assert target_components(KETTLE, _s("Boiling"), _s("Standby")) == {
        "power_button",
        "lid_release_button",
    }


def test_kettle_plan_from_an_axonometric_view() -> None:
    plan = plan_goals(
        KETTLE, _s("Standby"), "front_top", False, (_s("Boiling"), _s("BoilingComplete"))
    )
    assert plan.c_opt == (2, 1) and plan.transitions == (1, 1) and plan.switches == (1, 0)
    texts = [p.action.to_text() for p in plan.steps]
    assert texts[0] == "Switch_view(params=[front])"  # front is first in view order
    assert texts[1].startswith("Push(coord=[") and texts[1].endswith("params=[1])")
    assert texts[2] == "Timed_wait()"
    assert [KETTLE.states[s] for s in plan.states] == ["Boiling", "BoilingComplete", "Standby"]


def test_c_opt_dynamic() -> None:
    assert c_opt_dynamic(KETTLE, _s("Standby"), "front", False, _s("Boiling")) == 1
    assert c_opt_dynamic(KETTLE, _s("Standby"), "front_top", False, _s("Boiling")) == 2
    assert (
        c_opt_dynamic(KETTLE, _s("Standby"), "top", False, _s("Boiling")) == 2
    )  # no power button on top
    assert (
        c_opt_dynamic(KETTLE, _s("LidOpen"), "top", False, _s("Boiling")) == 3
    )  # lid on top, power not


# A: visible in front and back; B: only in back.
TWO_VIEWS = machine(
    {
        "S0": {
            "a_comp": [
                tr("S1", boxes=[box("front", 100, 100, 50, 50), box("back", 100, 100, 50, 50)])
            ]
        },
        "S1": {
            "b_comp": [tr("S2", boxes=[box("back", 500, 500, 50, 50)])],
            "a_comp": [
                tr("S0", boxes=[box("front", 100, 100, 50, 50), box("back", 100, 100, 50, 50)])
            ],
        },
        "S2": {"b_comp": [tr("S1", boxes=[box("back", 500, 500, 50, 50)])]},
    },
    "S0",
)


def test_switches_are_placed_as_late_as_possible() -> None:
    goals = (TWO_VIEWS.state_id("S1"), TWO_VIEWS.state_id("S2"))
    plan = plan_goals(TWO_VIEWS, TWO_VIEWS.state_id("S0"), "front", False, goals)
    # A in front (no switch), then switch to back for B: the switch lands in segment 2.
    assert plan.c_opt == (1, 2) and plan.switches == (0, 1)
    assert [p.action.type for p in plan.steps] == ["press", "switch_view", "press"]


def test_switch_minimisation_is_joint_over_goals() -> None:
    goals = (TWO_VIEWS.state_id("S1"), TWO_VIEWS.state_id("S2"))
    plan = plan_goals(TWO_VIEWS, TWO_VIEWS.state_id("S0"), "left", False, goals)
    # From left, A needs a switch anyway: going to back (not front, though front ranks first)
    # serves B too, so the whole plan has one switch.
    assert plan.c_opt == (2, 1)
    assert plan.steps[0].action.params == ("back",)


def test_view_order_breaks_ties() -> None:
    m = machine(
        {
            "S0": {"c": [tr("S1", boxes=[box("left", 1, 1, 9, 9), box("back", 1, 1, 9, 9)])]},
            "S1": {"c": [tr("S0", boxes=[box("back", 1, 1, 9, 9)])]},
        },
        "S0",
    )
    plan = plan_goals(m, m.state_id("S0"), "front", False, (m.state_id("S1"),))
    assert plan.steps[0].action.params == ("back",)  # back ranks before left


def test_safe_transitions_win_ties_over_dangerous_ones() -> None:
    b = [box("front", 10, 10, 20, 20)]
    m = machine(
        {
            "Init": {
                "go": [tr("Mid", boxes=b)],
                "tox": [tr("X", boxes=[box("front", 300, 300, 20, 20)])],
            },
            "Mid": {"fin": [tr("Goal", boxes=b)]},
            "Goal": {"reset": [tr("Init", boxes=b)]},
            "X": {
                "a_danger": [tr("Error", boxes=[box("front", 500, 500, 20, 20)])],
                "z_safe": [tr("Init", boxes=[box("front", 700, 700, 20, 20)])],
            },
            "Error": {"immediate": [tr("Init", action=None)]},
        },
        "Init",
    )
    task = msgspec.convert(
        {"episode_id": "e", "device_id": "dev", "goals": ["Goal"], "initial_state": "X"}, Task
    )
    setup = setup_episode(m, task)
    assert setup.plan.c_opt == (3,)
    assert [p.transition.component for p in setup.plan.steps] == ["z_safe", "go", "fin"]
    assert distances(m, m.state_id("Goal"))[m.state_id("X")] == 3


def test_dashboard_unlock_costs_one_or_two_switches() -> None:
    panel = [box("dashboard", 400, 400, 100, 100)]
    m = machine(
        {"Off": {"knob": [tr("On", boxes=panel)]}, "On": {"knob": [tr("Off", boxes=panel)]}},
        "Off",
        dashboard={"regions": [{"view": "top", "coordinate": [200, 200, 300, 300, 1000, 1000]}]},
    )
    on = (m.state_id("On"),)
    from_top = plan_goals(m, m.state_id("Off"), "top", False, on)
    assert from_top.c_opt == (2,)  # active unlock from top, then the knob
    assert from_top.steps[0].action.coord == (350.0, 350.0)
    from_front = plan_goals(m, m.state_id("Off"), "front", False, on)
    assert from_front.c_opt == (3,)  # switch to top, unlock, knob
    assert [p.action.params for p in from_front.steps[:2]] == [("top",), ("dashboard",)]
    assert plan_goals(m, m.state_id("Off"), "front", True, on).c_opt == (2,)  # already unlocked


@pytest.mark.parametrize(
    ("goals", "initial", "message"),
    [
        (["Standby"], None, "is the state in which it becomes current"),
        (["Boiling", "Boiling"], None, "goal 2 'Boiling' is the state in which it becomes current"),
        (["Nowhere"], None, "unknown goal state(s) 'Nowhere'"),
    ],
)
def test_unplannable_tasks_are_task_errors(goals, initial, message) -> None:
    task = msgspec.convert({"episode_id": "e", "device_id": "kettle", "goals": goals}, Task)
    with pytest.raises(TaskError, match=message.replace("(", r"\(").replace(")", r"\)")):
        setup_episode(KETTLE, task)


def test_unreachable_goal_is_reported() -> None:
    m = machine({"A": {"c": [tr("B", boxes=[box("front", 1, 1, 9, 9)])]}, "B": {}, "C": {}}, "A")
    with pytest.raises(TaskError, match="goal 1 'C' is unreachable from 'A'"):
        plan_goals(m, m.state_id("A"), "front", False, (m.state_id("C"),))
    hidden = machine({"A": {"c": [tr("B", boxes=[box("front_top", 1, 1, 9, 9)])]}, "B": {}}, "A")
    with pytest.raises(TaskError, match="no interactable view"):
        plan_goals(hidden, hidden.state_id("A"), "front", False, (hidden.state_id("B"),))


def test_the_optimal_next_step_follows_the_plan_from_wherever_the_episode_is() -> None:
    """PROTOCOL §4.5 on the kettle from the axonometric view: at reset the next step is the
    plan's first (switch to front); after it, the push; once Boiling is reached, the wait;
    with every goal completed there is none."""
    goals = (_s("Boiling"), _s("BoilingComplete"))
    plan = plan_goals(KETTLE, _s("Standby"), "front_top", False, goals)
    first = next_optimal_step(KETTLE, _s("Standby"), "front_top", False, goals)
    assert first == plan.steps[0] and first.action.to_text() == "Switch_view(params=[front])"
    after_switch = next_optimal_step(KETTLE, _s("Standby"), "front", False, goals)
    assert after_switch == plan.steps[1] and after_switch.action.type == "push"
    waiting = next_optimal_step(KETTLE, _s("Boiling"), "front", False, goals[1:])
    assert waiting is not None and waiting.action.to_text() == "Timed_wait()"
    assert next_optimal_step(KETTLE, _s("Standby"), "front", False, ()) is None


# ----------------------------------------------------------------------- exhaustive oracle

_PANEL = [box("dashboard", 400, 400, 100, 100)]
_POWER = [box("front", 10, 10, 50, 50), box("top", 10, 10, 50, 50)]
MIXED = machine(
    {
        "Off": {
            "power": [tr("Idle", boxes=_POWER)],
            "alt_power": [tr("Idle", boxes=[box("front", 100, 10, 50, 50)])],
            "shock": [tr("Error", boxes=[box("back", 10, 10, 50, 50)])],
        },
        "Idle": {
            "knob": [tr("Heating", boxes=_PANEL)],
            "power": [tr("Off", boxes=_POWER)],
            "lid": [tr("Open", boxes=[box("top", 300, 300, 50, 50), box("left", 300, 9, 50, 50)])],
        },
        "Open": {
            "lid": [tr("Idle", boxes=[box("top", 300, 300, 50, 50)])],
            "crush": [tr("Error", boxes=[box("left", 10, 10, 50, 50)])],
            "knob": [tr("Heating", boxes=_PANEL)],
        },
        "Heating": {"timed_wait": [tr("Ready", action=None)], "knob": [tr("Idle", boxes=_PANEL)]},
        "Ready": {"power": [tr("Off", boxes=_POWER)], "knob": [tr("Idle", boxes=_PANEL)]},
        "Error": {"immediate": [tr("Off", action=None)]},
    },
    "Off",
    dashboard={
        "regions": [
            {"view": "right", "coordinate": [200, 200, 300, 300, 1000, 1000]},
            {"view": "top", "coordinate": [600, 600, 300, 300, 1000, 1000]},
        ]
    },
)
"""Ties of every kind: two components alike but for their names, safe and dangerous ways,
boxes in several views, a dashboard unlocked from two views, a wait, an immediate chain."""

@pytest.mark.parametrize("m", [KETTLE, TWO_VIEWS, MIXED], ids=["kettle", "two_views", "mixed"])
def test_every_plan_is_the_exhaustive_optimum_with_its_tie_breaks(m) -> None:
    """From every state, view and dashboard state, for every sequence of one or two goals:
    the plan is the one a plain recursion over every option picks by PROTOCOL §4.3, and
    there is none exactly when the recursion finds none."""
    n = len(m.states)
    sequences = [(g,) for g in range(n)] + [(g, h) for g in range(n) for h in range(n)]
    planned = 0
    for goals in sequences:
        for s in range(n):
            if m.immediate_chain[s]:
                continue  # the agent never stands in a transient state
            for view in m.views:
                for unlocked in (False, True):
                    want = oracle_plan(m, goals, s, view, unlocked)
                    if want is None:
                        with pytest.raises(TaskError):
                            plan_goals(m, s, view, unlocked, goals)
                        continue
                    plan = plan_goals(m, s, view, unlocked, goals)
                    assert plan_steps(plan) == want, (goals, s, view, unlocked)
                    assert sum(plan.switches) == sum(len(pre) for pre, _ in want)
                    planned += 1
    assert planned > 100
