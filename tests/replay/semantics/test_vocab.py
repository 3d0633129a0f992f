"""The vocabularies' homes (PROTOCOL §2, §3): every table keyed by a protocol list has exactly
its keys, in its order, so a new termination or feedback kind is one line and this test."""

from __future__ import annotations

import replay.semantics as sem


def test_termination_texts_cover_the_terminations_exactly() -> None:
    assert list(sem.TERMINATION_TEXTS) == list(sem.TERMINATIONS)
    for ending in sem.TERMINATION_TEXTS.values():
        assert ending.label and ending.reason
        assert ending.reason[0].islower() and not ending.reason.endswith(".")  # a clause


def test_feedback_severity_covers_the_kinds_exactly() -> None:
    assert list(sem.FEEDBACK_SEVERITY) == list(sem.FEEDBACK_KINDS)
    assert set(sem.FEEDBACK_SEVERITY.values()) == set(sem.SEVERITIES)
    # Worked from PROTOCOL §3.6: the refused steps are errors, the steps that change nothing
    # warnings, the rest information.
    assert sem.FEEDBACK_SEVERITY[sem.FB_OPERATIONAL] == sem.ERROR
    assert sem.FEEDBACK_SEVERITY[sem.FB_INVALID] == sem.ERROR
    assert sem.FEEDBACK_SEVERITY[sem.FB_NULL] == sem.WARNING
    assert sem.FEEDBACK_SEVERITY[sem.FB_WAIT_NO_EFFECT] == sem.WARNING
    assert sem.FEEDBACK_SEVERITY[sem.FB_UNLOCKED] == sem.INFO


def test_parameter_codes_cover_the_interactions_exactly() -> None:
    assert list(sem.PARAMETER_CODES) == list(sem.INTERACTIONS)
    assert [len(codes) for codes in sem.PARAMETER_CODES.values()] == [3, 2, 5, 5, 2]


def test_view_lists() -> None:
    assert sem.VIEWS == (
        "front", "back", "left", "right", "top", "bottom", "front_top", "back_bottom", "dashboard"
    )  # fmt: skip
    assert sorted(sem.VIEW_ORDER) == sorted(sem.VIEWS)
    assert [sem.VIEW_RANK[v] for v in sem.VIEW_ORDER] == list(range(len(sem.VIEWS)))


def test_display_names() -> None:
    assert [sem.DISPLAY_NAMES[a] for a in sem.ACTION_NAMES] == [
        "Press", "Rotate", "Push", "Pull", "Grasp", "Switch_view", "Timed_wait"
    ]  # fmt: skip
