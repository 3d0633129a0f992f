"""Loading, validation (PROTOCOL §1.2) and compilation of state machines."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import msgspec
import pytest

from replay import (
    InputError,
    SSMError,
    StateMachine,
    compile_machine,
    load_machine,
    load_ssm,
)
from replay.io import decode_state_machine
from replay.semantics import validate_machine

DATA = Path(__file__).resolve().parents[2] / "data"
KETTLE = json.loads((DATA / "kettle_ssm.json").read_text())


def _errors(doc: dict) -> list[str]:
    ssm = msgspec.convert(doc, StateMachine)
    return [str(p) for p in validate_machine(ssm, "bad.json") if p.severity == "error"]


def test_paper_listings_load_verbatim() -> None:
    ssm = load_ssm(DATA / "kettle_ssm.json")
    assert ssm.name == "ElectricKettle" and ssm.initial_state == "Standby"
    assert set(ssm.states) == {"Standby", "Boiling", "LidOpen", "BoilingComplete", "Error"}
    ucsm = decode_state_machine(DATA / "kettle_ucsm.json")
    assert [
        p for p in validate_machine(ucsm, "ucsm", require_geometry=False) if p.severity == "error"
    ] == []


def test_kettle_compiles_to_the_normalised_geometry() -> None:
    m = load_machine(DATA / "kettle_ssm.json")
    assert m.device_id == "kettle_ssm"  # the file stem
    assert m.views == (
        "front",
        "back",
        "left",
        "right",
        "top",
        "bottom",
        "front_top",
        "back_bottom",
    )
    assert m.error_states == {m.state_id("Error")}
    # power_button front: [852, 955, 184, 76] in 1209 x 1369 -> x 852000/1209 = 704.7146..., etc.
    ((comp, rect),) = [cr for cr in m.component_rects["front"] if cr[0] == "power_button"]
    assert rect[0] == pytest.approx(704.714640, abs=1e-6)
    assert rect[1] == pytest.approx(697.589481, abs=1e-6)
    assert rect[2] == pytest.approx(704.714640 + 152.191894, abs=1e-6)
    assert rect[3] == pytest.approx(697.589481 + 55.514974, abs=1e-6)
    # BoilingComplete and Error are transient: their chains end in Standby.
    assert m.chain_end[m.state_id("Error")] == m.state_id("Standby")
    boil = m.state_id("Boiling")
    assert m.wait[boil] is not None and m.wait[boil].entered == (
        m.state_id("BoilingComplete"),
        m.state_id("Standby"),
    )
    lid_in_boiling = [t for t in m.by_state[boil] if t.component == "lid_release_button"][0]
    assert lid_in_boiling.dangerous and lid_in_boiling.end == m.state_id("Standby")


def _mutate(fn) -> dict:
    doc = copy.deepcopy(KETTLE)
    fn(doc)
    return doc


def _first_power(doc: dict) -> dict:
    return doc["states"]["Standby"]["on"]["power_button"][0]


@pytest.mark.parametrize(
    ("mutation", "needle"),
    [
        (lambda d: _first_power(d).update(next_state="Boilng"), "dangling next_state 'Boilng'"),
        (lambda d: d.update(initial_state="Idle"), "unknown initial_state 'Idle'"),
        (
            lambda d: d["states"]["Standby"]["on"].update(immediate=[{"next_state": "Error"}]),
            "cycle of immediate transitions: Standby -> Error -> Standby",
        ),
        (
            lambda d: _first_power(d)["bbox"][0].update(coordinate=[199, 815, 0, 57, 1138, 1122]),
            "non-positive size",
        ),
        (
            lambda d: _first_power(d)["bbox"][0].update(
                coordinate=[1100, 815, 143, 57, 1138, 1122]
            ),
            "outside its 1138 x 1122 image",
        ),
        (
            lambda d: _first_power(d).update(atomic_action="squeeze"),
            "unknown atomic action 'squeeze'",
        ),
        (
            lambda d: _first_power(d)["bbox"][0].update(view="inside"),
            "bbox on unknown view 'inside'",
        ),
        (
            lambda d: _first_power(d)["bbox"][0].update(view="dashboard"),
            "bbox on unknown view 'dashboard'",
        ),
        (
            lambda d: _first_power(d)["bbox"][0].update(coordinate=[1, 2, 3]),
            "must be [x, y, w, h, W, H]",
        ),
    ],
    ids=[
        "dangling",
        "initial",
        "immediate-cycle",
        "size",
        "outside",
        "action",
        "view",
        "dashboard-view",
        "short",
    ],
)
def test_each_problem_is_named(mutation, needle: str) -> None:
    errors = _errors(_mutate(mutation))
    assert any(needle in e for e in errors), errors
    hit = [e for e in errors if needle in e][0]
    assert hit.startswith("bad.json")
    if needle.startswith(("dangling", "non-positive", "outside", "unknown atomic", "bbox on")):
        assert "state 'Standby', component 'power_button', transition 0" in hit


def test_a_box_with_two_problems_has_both_named_at_its_place() -> None:
    # 0 wide and past the left edge: two errors, each at the box, numbers as written
    box = [-5, 815, 0, 57.5, 1138, 1122]
    errors = _errors(_mutate(lambda d: _first_power(d)["bbox"][0].update(coordinate=box)))
    at = "state 'Standby', component 'power_button', transition 0, bbox 0"
    assert [e for e in errors if at in e] == [
        f"bad.json [{at}]: bbox with non-positive size w=0, h=57.5",
        f"bad.json [{at}]: bbox [-5, 815, 0, 57.5] outside its 1138 x 1122 image",
    ]


def test_all_problems_are_reported_not_just_the_first(tmp_path: Path) -> None:
    def two_faults(d: dict) -> None:
        _first_power(d).update(next_state="Nowhere")
        d["states"]["LidOpen"]["on"]["power_button"][0]["atomic_action"] = "twist"

    path = tmp_path / "two.json"
    path.write_text(json.dumps(_mutate(two_faults)))
    with pytest.raises(SSMError) as info:
        load_ssm(path)
    messages = [str(p) for p in info.value.problems]
    assert len(messages) == 2
    assert "Nowhere" in messages[0] and "twist" in messages[1]
    assert "and 1 more" in str(info.value)
    with pytest.raises(SSMError):
        compile_machine(decode_state_machine(path))


def test_bad_json_names_file_and_line(tmp_path: Path) -> None:
    path = tmp_path / "broken.json"
    path.write_text('{\n  "name": "X",\n  "initial_state": "A",\n  "states": {,}\n}\n')
    with pytest.raises(InputError) as info:
        load_ssm(path)
    assert info.value.line == 4
    assert str(info.value).startswith(f"{path}:4: ")
    wrong_type = tmp_path / "wrong.json"
    wrong_type.write_text('{"name": "X", "initial_state": 3, "states": {}}')
    with pytest.raises(InputError, match=r"initial_state"):
        load_ssm(wrong_type)


def test_missing_file_is_a_clear_error(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="file not found"):
        load_ssm(tmp_path / "nope.json")


def test_dashboard_extension_adds_the_view() -> None:
    doc = _mutate(
        lambda d: d.update(
            dashboard={
                "regions": [{"view": "front", "coordinate": [800, 900, 300, 200, 1209, 1369]}]
            }
        )
    )
    m = compile_machine(msgspec.convert(doc, StateMachine))
    assert m.views[-3:] == ("dashboard", "front_top", "back_bottom")
    assert m.in_dashboard_region("front", 700, 700) and not m.in_dashboard_region("back", 700, 700)
    bad = _mutate(
        lambda d: d.update(
            dashboard={"regions": [{"view": "front_top", "coordinate": [1, 1, 5, 5, 100, 100]}]}
        )
    )
    assert any("regions must be on orthographic views" in e for e in _errors(bad))


def test_warnings_do_not_block() -> None:
    doc = _mutate(
        lambda d: d["states"]["Boiling"]["on"]["timed_wait"][0].update(
            bbox=[{"coordinate": [1, 1, 2, 2, 10, 10], "view": "front"}]
        )
    )
    ssm = msgspec.convert(doc, StateMachine)
    problems = validate_machine(ssm, "w.json")
    assert [p.severity for p in problems] == ["warning"]
    compile_machine(ssm)
