"""The action grammar (PROTOCOL §2): a table of valid and invalid responses, and a fuzz test."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from replay import Action, parse_action
from replay.semantics import action_from_record

OK = "ok"

# (response text, expected detail or OK, expected action when OK)
CASES: list[tuple[str, str, Action | None]] = [
    # --- the paper's own examples
    (
        "Thinking: dial.\nAction: Rotate(coord=[850, 720], params=[0, 2])",
        OK,
        Action("rotate", (850.0, 720.0), ("0", "2")),
    ),
    (
        "Thinking: bottom.\nAction: Switch_view(params=[bottom])",
        OK,
        Action("switch_view", None, ("bottom",)),
    ),
    ("Thinking: wait.\nAction: Timed_wait()", OK, Action("timed_wait", None, ())),
    (
        "Thinking: zoom.\nAction: Switch_view(coord=[850, 720], params=[dashboard])",
        OK,
        Action("switch_view", (850.0, 720.0), ("dashboard",)),
    ),
    ("Thinking: the button.\nAction: Click(params=[701, 303])", "unknown_action", None),
    (
        "Thinking: release.\nAction: Press(coord=[500, 280], params=[0])",
        OK,
        Action("press", (500.0, 280.0), ("0",)),
    ),
    ("Action: Push(coord=[285, 620], params=[0])", OK, Action("push", (285.0, 620.0), ("0",))),
    ("Action: Pull(coord=[500, 420], params=[1])", OK, Action("pull", (500.0, 420.0), ("1",))),
    # --- names are case-insensitive
    ("Action: press(coord=[1, 2], params=[0])", OK, Action("press", (1.0, 2.0), ("0",))),
    ("Action: PRESS(coord=[1, 2], params=[0])", OK, Action("press", (1.0, 2.0), ("0",))),
    ("Action: switch_VIEW(params=[Top])", OK, Action("switch_view", None, ("top",))),
    ("action: Grasp(coord=[10, 20], params=[0])", OK, Action("grasp", (10.0, 20.0), ("0",))),
    # --- quotes around params, * params
    ("Action: Switch_view(params=['bottom'])", OK, Action("switch_view", None, ("bottom",))),
    ('Action: Switch_view(params=["bottom"])', OK, Action("switch_view", None, ("bottom",))),
    ("Action: Rotate(coord=[5, 5], params=[*, 2])", OK, Action("rotate", (5.0, 5.0), ("*", "2"))),
    (
        "Action: Rotate(coord=[5, 5], params=['*', '*'])",
        OK,
        Action("rotate", (5.0, 5.0), ("*", "*")),
    ),
    # --- whitespace, decimals, trailing period, argument order, trailing comma
    (
        "Action:Press( coord = [ 500 , 300 ] , params = [ 0 ] )",
        OK,
        Action("press", (500.0, 300.0), ("0",)),
    ),
    (
        "Action: Press(coord=[500.5, 300.25], params=[0])",
        OK,
        Action("press", (500.5, 300.25), ("0",)),
    ),
    ("Action: Press(coord=[500, 300], params=[0]).", OK, Action("press", (500.0, 300.0), ("0",))),
    ("Action: Press(params=[1], coord=[500, 300])", OK, Action("press", (500.0, 300.0), ("1",))),
    ("Action: Press(coord=[500, 300], params=[0],)", OK, Action("press", (500.0, 300.0), ("0",))),
    ("Action: Press(coord=[500, 300], params=[1.0])", OK, Action("press", (500.0, 300.0), ("1",))),
    ("Action: Press(coord=[500, 300])", OK, Action("press", (500.0, 300.0), ())),
    ("Action: Press(coord=[500, 300], params=[])", OK, Action("press", (500.0, 300.0), ())),
    ("Action: Timed_wait(params=[])", OK, Action("timed_wait", None, ())),
    ("Action: Switch_view(params=top)", OK, Action("switch_view", None, ("top",))),
    ("Action: Press(coord=(500, 300), params=(0,))", OK, Action("press", (500.0, 300.0), ("0",))),
    ("Action: Press(coord=[-5, 1200], params=[0])", OK, Action("press", (-5.0, 1200.0), ("0",))),
    # --- markdown: code fences, bold, backticks, quotes of the label
    (
        "Thinking: x\n**Action:** Press(coord=[1, 2], params=[0])",
        OK,
        Action("press", (1.0, 2.0), ("0",)),
    ),
    (
        "Thinking: x\n**Action**: `Press(coord=[1, 2], params=[0])`",
        OK,
        Action("press", (1.0, 2.0), ("0",)),
    ),
    (
        "Thinking: x\nAction:\n```\nPress(coord=[1, 2], params=[0])\n```",
        OK,
        Action("press", (1.0, 2.0), ("0",)),
    ),
    ("Thinking: x\nAction:\n```python\nTimed_wait()\n```\n", OK, Action("timed_wait", None, ())),
    (
        "Thinking: x\n- Action: **Pull(coord=[3, 4], params=[4])**",
        OK,
        Action("pull", (3.0, 4.0), ("4",)),
    ),
    (
        "Thinking: x\n### Action: Push(coord=[3, 4], params=[4])",
        OK,
        Action("push", (3.0, 4.0), ("4",)),
    ),
    # --- a label mid-line when there is no line-start label; trailing prose is ignored
    (
        "Thinking: a knob. Action: Rotate(coord=[1, 1], params=[0, 1])",
        OK,
        Action("rotate", (1.0, 1.0), ("0", "1")),
    ),
    (
        "Action: Press(coord=[1, 2], params=[0])\nThis should turn it on (hopefully).",
        OK,
        Action("press", (1.0, 2.0), ("0",)),
    ),
    # --- failures: no action
    ("", "no_action", None),
    ("Thinking: I am not sure what to do.", "no_action", None),
    ("Press(coord=[1, 2], params=[0])", "no_action", None),
    # --- failures: more than one
    ("Action: Press(coord=[1, 2], params=[0])\nAction: Timed_wait()", "multiple_actions", None),
    (
        "Action: Press(coord=[1, 2], params=[0]); Rotate(coord=[3, 4], params=[0, 1])",
        "multiple_actions",
        None,
    ),
    (
        "Action: Switch_view(params=[top]) then Press(coord=[1,2], params=[0])",
        "multiple_actions",
        None,
    ),
    # --- failures: unknown names
    ("Action: Tap(coord=[1, 2])", "unknown_action", None),
    ("Action: Wait()", "unknown_action", None),
    # --- failures: malformed
    ("Action: Press", "malformed", None),
    ("Action: press the red button", "malformed", None),
    ("Action: Press(coord=[1, 2], params=[0]", "malformed", None),
    ("Action: Press(coord=[1], params=[0])", "malformed", None),
    ("Action: Press(coord=[1, 2, 3], params=[0])", "malformed", None),
    ("Action: Press(coord=[a, b], params=[0])", "malformed", None),
    ("Action: Press(button=3)", "malformed", None),
    ("Action: Press([1, 2], [0])", "malformed", None),
    ("Action: Press(coord=[1, 2], coord=[3, 4])", "malformed", None),
    ("Action: Press(coord=[1, 2] params=[0])", "malformed", None),
    ("Action: Press(coord=[1, 2], params=['0)", "malformed", None),
    ("Action:", "malformed", None),
    ("Action: Press(,)", "malformed", None),
    ("Action: Press(coord=[1e999, 5], params=[0])", "malformed", None),
    ("Action: Press(coord=[" + "9" * 400 + ", 5], params=[0])", "malformed", None),
    ("Action: Press(coord=[1, 2], params=[,])", "malformed", None),
    ("Action: Press(coord=[1, 2], params=[ ])", OK, Action("press", (1.0, 2.0), ())),
    ("Action: Press(coord=[1, 2],, params=[0])", "malformed", None),
    ("Action: Rotate(coord=[1, 2], params=[0,,1])", "malformed", None),
]


def test_table_is_large_enough() -> None:
    assert len(CASES) >= 40
    details = {d for _, d, _ in CASES}
    assert {"no_action", "multiple_actions", "unknown_action", "malformed", OK} <= details


@pytest.mark.parametrize(("text", "detail", "action"), CASES, ids=[c[0][:60] for c in CASES])
def test_parse_table(text: str, detail: str, action: Action | None) -> None:
    parsed = parse_action(text)
    if detail == OK:
        assert parsed.ok, parsed
        assert parsed.detail is None
        assert parsed.action == action
    else:
        assert not parsed.ok
        assert parsed.action is None
        assert parsed.detail == detail


def test_thinking_is_extracted() -> None:
    parsed = parse_action("Thinking: The knob is at the bottom right.\nAction: Timed_wait()")
    assert parsed.thinking == "The knob is at the bottom right."
    assert parsed.action_text == "Timed_wait()"


def test_action_to_text_round_trips() -> None:
    for _text, detail, action in CASES:
        if detail == OK and action is not None:
            again = parse_action("Action: " + action.to_text())
            assert again.ok and again.action == action, action.to_text()


@pytest.mark.parametrize(
    ("record", "detail", "action"),
    [
        (("Press", [500, 300], [0]), OK, Action("press", (500.0, 300.0), ("0",))),
        (("switch_view", None, ["Front"]), OK, Action("switch_view", None, ("front",))),
        (("Timed_wait", None, []), OK, Action("timed_wait", None, ())),
        (("Click", [1, 2], []), "unknown_action", None),
        (("Press", [1, 2, 3], [0]), "malformed", None),
        (("Press", [float("nan"), 2], [0]), "malformed", None),
    ],
)
def test_structured_actions(record, detail, action) -> None:
    parsed = action_from_record(*record)
    if detail == OK:
        assert parsed.ok and parsed.action == action
    else:
        assert not parsed.ok and parsed.detail == detail


_ACTIONISH = st.sampled_from(
    [
        "Action:",
        "action :",
        "**Action:**",
        "Thinking:",
        "Press(",
        "Rotate(",
        "Switch_view(",
        "Timed_wait()",
        "coord=",
        "params=",
        "[",
        "]",
        "(",
        ")",
        ",",
        "'",
        '"',
        "*",
        "```",
        "\n",
        " ",
        "500",
        "-3.5e2",
        "dashboard",
    ]
)


@settings(max_examples=400, deadline=None)
@given(st.text(max_size=300))
def test_never_raises_on_any_text(text: str) -> None:
    parsed = parse_action(text)
    assert parsed.ok == (parsed.action is not None)
    assert parsed.ok or parsed.detail in {
        "no_action",
        "multiple_actions",
        "unknown_action",
        "malformed",
    }


@settings(max_examples=400, deadline=None)
@given(st.lists(_ACTIONISH | st.text(max_size=5), max_size=40).map("".join))
def test_never_raises_on_action_like_text(text: str) -> None:
    parsed = parse_action(text)
    assert parsed.ok == (parsed.action is not None)
    if parsed.ok:
        assert parsed.action.type in {
            "press",
            "rotate",
            "push",
            "pull",
            "grasp",
            "switch_view",
            "timed_wait",
        }


_COORD = st.one_of(
    st.integers(-20, 1020).map(str), st.floats(-20, 1020, allow_nan=False).map(lambda f: f"{f:.2f}")
)
_PARAM = st.sampled_from(
    ["0", "1", "2", "4", "*", "top", "dashboard", "1.0", "01", "-1", "back_bottom", "", " ", "a b"]
)


@settings(max_examples=500, deadline=None)
@given(
    st.sampled_from(
        ["Press", "rotate", "PUSH", "Pull", "Grasp", "Switch_view", "Timed_wait", "Click"]
    ),
    st.none() | st.tuples(_COORD, _COORD),
    st.none()
    | st.lists(st.tuples(_PARAM, st.sampled_from(["", "'", '"', "''", "'\""])), max_size=3),
    st.sampled_from(["", " ", ", ", "  ,  "]),
    st.sampled_from(
        ["", ".", " .", "\n", " \n\n", "` .", "**", "`\nmore prose", "\n```", "\n```\n", " ```"]
    ),
    st.sampled_from(["", "`", "**", "``", "*", "** ", "\n```\n", "```python\n", "\n```"]),
)
def test_fast_path_agrees_with_the_full_grammar(name, coord, params, sep, tail, lead) -> None:
    from replay.semantics._parse import _parse_entry, _parse_entry_full

    args = []
    if coord is not None:
        args.append(f"coord=[{coord[0]}, {coord[1]}]")
    if params is not None:
        # quote styles: none, 'x', "x", ''x'' (two levels), 'x" (unbalanced)
        quoted = [
            q + p + q if len(q) < 2 else q + p + q if q == "''" else q[0] + p + q[1]
            for p, q in params
        ]
        args.append("params=[" + ", ".join(quoted) + "]")
    entry = " " + lead + f"{name}(" + sep.join(args) + ")" + tail
    assert _parse_entry(entry, "") == _parse_entry_full(entry, "")


@settings(max_examples=400, deadline=None)
@given(
    st.lists(
        _ACTIONISH
        | st.sampled_from(["ACTION", "x", "_action:", "Actions:", "İ", "\t", "-"])
        | st.text(max_size=4),
        max_size=30,
    ).map("".join)
)
def test_label_scanner_matches_the_regexes(text: str) -> None:
    from replay.semantics._parse import _LABEL_ANY, _LABEL_LINE, _find_labels

    found = list(_LABEL_LINE.finditer(text)) or list(_LABEL_ANY.finditer(text))
    assert _find_labels(text) == [(m.start(), m.end()) for m in found]
