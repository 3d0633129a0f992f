"""The pure step function (PROTOCOL §3) on small hand-written machines."""

from __future__ import annotations

from pathlib import Path

from hypothesis import given, settings
from hypothesis import strategies as st

from replay import SimState, load_machine, parse_action, step

from ..machines import box, machine, tr

KETTLE = load_machine(Path(__file__).resolve().parents[2] / "data" / "kettle_ssm.json", "kettle")

# Two overlapping components: `big` (a panel) and `small` (a button on it), both pressable.
OVERLAP = machine(
    {
        "Idle": {
            "big": [tr("Panel", boxes=[box("front", 100, 100, 400, 400)])],
            "small": [
                tr("Button", boxes=[box("front", 200, 200, 50, 50)]),
                tr("Held", params=("1",), boxes=[box("front", 200, 200, 50, 50)]),
            ],
        },
        "Panel": {"big": [tr("Idle", boxes=[box("front", 100, 100, 400, 400)])]},
        "Button": {
            "small": [tr("Idle", boxes=[box("front", 200, 200, 50, 50)])],
            "other": [tr("Idle", boxes=[box("front", 800, 800, 50, 50)])],
        },
        "Held": {"small": [tr("Idle", params=("*",), boxes=[box("front", 200, 200, 50, 50)])]},
    },
    "Idle",
)


def _do(m, sim, text):
    return step(m, sim, parse_action("Action: " + text))


def test_smallest_bbox_wins_among_matches() -> None:
    sim = SimState(OVERLAP.state_id("Idle"), "front", False)
    new, out = _do(OVERLAP, sim, "Press(coord=[210, 210], params=[0])")
    assert out.kind == "transition" and out.transition.component == "small"
    assert OVERLAP.states[new.state] == "Button"
    new, out = _do(OVERLAP, sim, "Press(coord=[110, 110], params=[0])")
    assert OVERLAP.states[new.state] == "Panel"
    # Params pick among the transitions of one component.
    new, _ = _do(OVERLAP, sim, "Press(coord=[210, 210], params=[1])")
    assert OVERLAP.states[new.state] == "Held"
    # A smaller component that does not match falls back to the larger one that does? No:
    # `big` has no params-1 transition, `small` does, so `small` still wins; with params 2 neither
    # matches but both were hit -> operational error.
    _, out = _do(OVERLAP, sim, "Press(coord=[210, 210], params=[2])")
    assert out.kind == "operational_error"


def test_wildcard_params_and_component_of_another_state() -> None:
    held = SimState(OVERLAP.state_id("Held"), "front", False)
    new, out = _do(OVERLAP, held, "Press(coord=[210, 210], params=[7])")
    assert out.kind == "transition" and OVERLAP.states[new.state] == "Idle"
    _, out = _do(OVERLAP, held, "Press(coord=[210, 210], params=[])")
    assert out.kind == "operational_error"  # '*' needs a value at that position
    # `other` only reacts in Button: a click on it elsewhere is a null effect.
    _, out = _do(OVERLAP, held, "Press(coord=[820, 820], params=[0])")
    assert out.kind == "null_effect"
    _, out = _do(OVERLAP, held, "Press(coord=[990, 10], params=[0])")
    assert out.kind == "null_effect"


def test_validity_checks_come_in_spec_order() -> None:
    standby = KETTLE.state_id("Standby")
    axo = SimState(standby, "front_top", False)
    _, out = _do(KETTLE, axo, "Push(params=[1])")
    assert (out.kind, out.detail) == ("invalid_action", "axonometric_view")
    front = SimState(standby, "front", False)
    _, out = _do(KETTLE, front, "Push(params=[1])")
    assert (out.kind, out.detail) == ("invalid_action", "missing_coord")
    _, out = _do(KETTLE, front, "Push(coord=[1000.5, 3], params=[1])")
    assert (out.kind, out.detail) == ("invalid_action", "out_of_range")
    assert out.text.startswith("System Notification:")
    new, out = _do(KETTLE, front, "Push(coord=[1000, 1000], params=[1])")
    assert out.kind == "null_effect" and new == front


def test_switch_view_rules() -> None:
    front = SimState(KETTLE.state_id("Standby"), "front", False)
    new, out = _do(KETTLE, front, "Switch_view(params=[front])")
    assert out.kind == "view_switched" and new == front  # a useless switch is still a switch
    new, out = _do(KETTLE, front, "Switch_view(params=[BACK_bottom])")
    assert out.switched and new.view == "back_bottom"
    for bad in (
        "Switch_view(params=[dashboard])",
        "Switch_view(params=[inside])",
        "Switch_view()",
        "Switch_view(params=[top, left])",
    ):
        new, out = _do(KETTLE, front, bad)
        assert (out.kind, out.detail, new) == ("invalid_action", "invalid_view", front), bad


def test_timed_wait_and_dangerous_chain() -> None:
    boiling = SimState(KETTLE.state_id("Boiling"), "front", False)
    new, out = _do(KETTLE, boiling, "Timed_wait()")
    assert out.kind == "transition" and [KETTLE.states[s] for s in out.entered] == [
        "BoilingComplete",
        "Standby",
    ]
    _, out = _do(KETTLE, new, "Timed_wait()")
    assert out.kind == "wait_no_effect"
    new, out = _do(KETTLE, boiling, "Push(coord=[780, 70], params=[1])")  # lid while boiling
    assert out.dangerous and [KETTLE.states[s] for s in out.entered] == ["Error", "Standby"]
    assert "dangerous operation" in out.text and KETTLE.states[new.state] == "Standby"


def test_parse_failures_change_nothing() -> None:
    sim = SimState(KETTLE.state_id("Boiling"), "top", False)
    for text in (
        "Thinking: hmm",
        "Action: Click(params=[1])",
        "Action: Press(coord=[1, 2]",
        "Action: Timed_wait()\nAction: Timed_wait()",
    ):
        new, out = step(KETTLE, sim, parse_action(text))
        assert new == sim and out.kind == "invalid_action"


@settings(max_examples=300, deadline=None)
@given(
    st.sampled_from([s for i, s in enumerate(KETTLE.states) if not KETTLE.immediate_chain[i]]),
    st.sampled_from(KETTLE.views),
    st.sampled_from(["Press", "Push", "Rotate", "Pull", "Grasp"]),
    st.floats(-50, 1050, allow_nan=False),
    st.floats(-50, 1050, allow_nan=False),
    st.sampled_from(["0", "1", "2", "*"]),
)
def test_step_is_pure_and_total(state, view, name, x, y, param) -> None:
    sim = SimState(KETTLE.state_id(state), view, False)
    parsed = parse_action(f"Action: {name}(coord=[{x}, {y}], params=[{param}])")
    first = step(KETTLE, sim, parsed)
    second = step(KETTLE, sim, parsed)
    assert first == second  # no hidden state, no randomness
    new, out = first
    assert out.kind in {"invalid_action", "transition", "operational_error", "null_effect"}
    assert (out.kind == "transition") == (out.transition is not None)
    assert KETTLE.immediate_chain[new.state] == ()  # the agent never rests in a transient state
