"""The kernel reads a logged step's fields as UTF-8 (`StepIn`): recorded views, feedback and
states outside ASCII are compared and written as the reference compares and writes the str,
and each kind of timestamp gives the reference's seconds."""

from __future__ import annotations

import replay
from replay.kernel import EpisodeInput, replay_kernel

from ..machines import box, machine, tr
from .test_kernel import check_batch, episode

SWITCH = "Thinking: t.\nAction: Switch_view(params=[{}])"
PRESS = "Thinking: t.\nAction: Press(coord=[125, 125], params=[0])"
ON_TEXT = "Allumé ☕. Now: Marche state."
"""The replay's feedback text of the press below (its description, then the state)."""


def _cafe() -> tuple[replay.Machine, replay.Task]:
    """States and a feedback text outside ASCII; a button on the front and one on the back."""
    on = {
        "Arrêt": {
            "bouton": [tr("Marche", boxes=[box("front", 100, 100, 50, 50)], text="Allumé ☕")],
            "dos": [tr("Arrêt", boxes=[box("back", 100, 100, 50, 50)], text="Rien")],
        },
        "Marche": {"bouton": [tr("Arrêt", boxes=[box("front", 100, 100, 50, 50)])]},
    }
    return machine(on, "Arrêt"), replay.Task(episode_id="cafe", device_id="dev", goals=["Marche"])


def _columns(e: EpisodeInput, *names: str) -> list[tuple]:
    steps = replay_kernel([e], run_id="r", model="m", agent_kind="vlm").steps
    return list(zip(*(steps[n].to_pylist() for n in names), strict=True))


def test_views_lowered_as_str_lower_does() -> None:
    """A recorded view is the replay's when its `str.lower()` is: the Kelvin sign (U+212A)
    lowers to an ASCII 'k', so "bacK" with it is the back view; a Cyrillic 'с' is no 'c'."""
    m, task = _cafe()
    views = ["bac\u212a", "BACK", "BAC\u212a", "ba\u0441k", "back_bottom", "Back "]
    steps = [{"output": SWITCH.format("back"), "view": v} for v in views]
    e = episode(m, task, steps, 20.0)  # a budget of 20 steps: none truncated
    check_batch([e])
    assert _columns(e, "view_after", "recorded_view", "diverged", "diverged_fields") == [
        ("back", "bac\u212a", False, []),
        ("back", "BACK", False, []),
        ("back", "BAC\u212a", False, []),
        ("back", "ba\u0441k", True, ["view"]),
        ("back", "back_bottom", True, ["view"]),
        ("back", "Back ", True, ["view"]),
    ]


def test_texts_outside_ascii_compared_and_written() -> None:
    """Recorded feedback texts and states outside ASCII: equal to the replay's only when
    every character is; written to the recorded columns as they were logged."""
    m, task = _cafe()
    steps = [
        {"output": PRESS, "feedback": ON_TEXT, "state": "Marche"},  # equal
        {"output": PRESS, "feedback": "Allumé ☕.", "state": "Arrêt"},  # a shorter text
        {"output": PRESS, "feedback": "transition", "state": "Arrét"},  # an accent moved
    ]
    e = episode(m, task, steps, 5.0)
    check_batch([e])
    got = _columns(
        e, "state_after", "recorded_feedback", "recorded_state", "diverged", "diverged_fields"
    )
    assert got == [
        ("Marche", ON_TEXT, "Marche", False, []),
        # the goal was reached at step 0: the log's later steps are truncated, not compared
        (None, "Allumé ☕.", "Arrêt", None, []),
        (None, "transition", "Arrét", None, []),
    ]
    # Compared while the episode runs: a two-goal task keeps it going.
    task2 = replay.Task(episode_id="cafe2", device_id="dev", goals=["Marche", "Arrêt"])
    steps = [
        {"output": PRESS, "feedback": "Allumé ☕.", "state": "Marche"},
        {"output": PRESS, "feedback": "Éteint", "state": "Arrét"},
    ]
    e = episode(m, task2, steps, 5.0)
    check_batch([e])
    got = _columns(e, "feedback_text", "recorded_state", "diverged_fields")
    assert got == [
        (ON_TEXT, "Marche", ["feedback"]),
        ("to Arrêt. Now: Arrêt state.", "Arrét", ["feedback", "state"]),
    ]


def test_timestamps_of_each_kind() -> None:
    """Numbers are seconds; ISO 8601 texts (spaces around them stripped, NBSP included) are
    read as `timestamp_seconds` reads them, 2026-01-02T03:04:05Z being 1,767,323,045 s
    (20,455 days after 1970-01-01, and 3 h 4 min 5 s); a text that is no time, and no
    timestamp, give null; a str without UTF-8 and an int, set on a `LogStep` (msgspec
    decodes neither), are read by `timestamp_seconds` too."""
    m, task = _cafe()
    stamps = [1_700_000_000.5, 1_700_000_001, "2026-01-02T03:04:05Z",
              "\u00a02026-01-02T03:04:05Z ", "soon", "\u00e9t\u00e9", None, None, None]  # fmt: skip
    steps = [{"output": SWITCH.format("back"), "timestamp": t} for t in stamps]
    e = episode(m, task, steps, 20.0)
    e.log.steps[-2].timestamp = "\ud800"  # no UTF-8 (msgspec declines the line): no time
    e.log.steps[-1].timestamp = 7  # an int: msgspec would have made it a float
    check_batch([e])
    assert [t for (t,) in _columns(e, "timestamp")] == [
        1_700_000_000.5, 1_700_000_001.0, 1_767_323_045.0, 1_767_323_045.0, None, None, None, None, 7.0,
    ]  # fmt: skip
    assert 20_455 * 86_400 + 3 * 3600 + 4 * 60 + 5 == 1_767_323_045


class _Fresh:
    """A logged step that is no `LogStep`: its texts are made anew on each read."""

    action = None
    prompt_tokens = completion_tokens = latency_seconds = None

    def __init__(self, view: str) -> None:
        self._view = view

    output = property(lambda self: "".join([SWITCH[:21], SWITCH[21:].format("back")]))
    view = property(lambda self: "".join(self._view))
    feedback = property(lambda self: "".join(["view_", "switched"]))
    state = property(lambda self: "".join(["Arr", "êt"]))
    timestamp = property(lambda self: "".join(["2026-01-02", "T03:04:05Z"]))


def test_steps_that_are_no_log_steps() -> None:
    """Steps of another type (a subclass of `LogStep`, a stand-in whose fields are made on
    each read) are read by their attributes, and give the reference's rows."""

    class Sub(replay.LogStep):
        pass

    m, task = _cafe()
    front = Sub(output=SWITCH.format("front"), view="front", feedback="view_switched")
    steps = [_Fresh("bac\u212a"), front, _Fresh("x")]
    log = replay.EpisodeLog(episode_id="cafe", steps=steps)
    e = episode(m, task, [], 20.0)._replace(log=log)
    check_batch([e])
    assert _columns(e, "recorded_view", "recorded_state", "diverged_fields", "timestamp") == [
        ("bac\u212a", "Arrêt", [], 1_767_323_045.0),
        ("front", None, [], None),
        ("x", "Arrêt", ["view"], 1_767_323_045.0),
    ]
