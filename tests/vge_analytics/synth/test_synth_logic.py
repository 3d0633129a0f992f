"""The logical half of instantiation: which functions a device keeps, and the SSM totals it
gives the full benchmark against the paper's Table "Data statistics"."""

from __future__ import annotations

import json
import random
from pathlib import Path

from vge_analytics.synth import SCALES, device_logic, plan_devices
from vge_analytics.synth._instantiate import dashboard_probability
from vge_analytics.synth._logic import _drop_functions

SAMPLE_SSM = Path(__file__).resolve().parents[3] / "logs" / "bench" / "ssm"


def _t(next_state: str) -> dict:
    return {"next_state": next_state, "transition_description": next_state}


def _washer() -> dict[str, dict]:
    """A start button that passes through a filling phase, a dial that starts the same wash
    directly, and a knob whose nudge during the wash settles back where it was."""
    return {
        "Off": {"on": {"start": [_t("Filling")], "dial": [_t("Washing")], "knob": [_t("Low")]}},
        "Filling": {"on": {"immediate": [_t("Washing")]}},
        "Washing": {"on": {"start": [_t("Off")], "knob": [_t("WashAdjust")]}},
        "WashAdjust": {"on": {"immediate": [_t("Washing")]}},
        "Low": {"on": {"knob": [_t("Off")]}},
    }


def test_a_settling_state_on_the_way_is_never_dropped_as_a_function():
    # Every draw is below the drop rate, so each state is dropped unless a rule keeps it:
    # Off is the initial state; Filling passes the device on to Washing (part of the start
    # button's transition); dropping Washing would leave a single goal; WashAdjust returns
    # the device to where it was (an optional nudge) and goes; Low is then the knob's only
    # use that changes the state, so it stays.
    kept = _drop_functions(_washer(), "Off", {"Off", "Washing", "Low"}, 1.0, random.Random(0))
    assert list(kept) == ["Off", "Filling", "Washing", "Low"]
    assert kept["Off"]["on"]["start"] == [_t("Filling")]
    assert kept["Washing"]["on"] == {"start": [_t("Off")]}


def _without_geometry(ssm: dict) -> dict:
    """An SSM file as `DeviceLogic.machine` states it: no bboxes, views or dashboard."""

    def state(sdef: dict) -> dict:
        on = {
            comp: [{k: v for k, v in t.items() if k != "bbox"} for t in trans]
            for comp, trans in sdef["on"].items()
        }
        return {**sdef, "on": on}

    return {
        "name": ssm["name"],
        "initial_state": ssm["initial_state"],
        "states": {name: state(sdef) for name, sdef in ssm["states"].items()},
    }


def test_device_logic_is_the_logic_of_the_written_ssm():
    # logs/ is `vge synth --scale sample --seed 0` byte for byte (test_synth_bench.py): its
    # SSM files are what the whole pipeline (logic, layout and its retries, assembly) wrote.
    # device_logic, which skips the layout, must give each file's states and transitions,
    # and as components exactly those the file gives boxes to.
    p = dashboard_probability()
    jobs = plan_devices(SCALES["sample"], 0)
    assert sorted(j.device_id for j in jobs) == sorted(f.stem for f in SAMPLE_SSM.glob("*.json"))
    for job in jobs:
        written = json.loads((SAMPLE_SSM / f"{job.device_id}.json").read_text(encoding="utf-8"))
        logic = device_logic(job.category, job.device_id, 0, dashboard_p=p)
        assert json.loads(json.dumps(logic.machine)) == _without_geometry(written), job.device_id
        boxed = {
            comp
            for sdef in written["states"].values()
            for comp, trans in sdef["on"].items()
            if any("bbox" in t for t in trans)
        }
        assert set(logic.components) == boxed, job.device_id


# The paper's Table "Data statistics" and atomic action table (operable = every transition
# but `immediate`, timed waits included).
PAPER = {"states": 6352, "transitions": 15861, "operable": 14404, "components": 3712}
# What `vge synth --scale full --seed 0` writes (docs/SYNTHETIC.md, "Statistics at full
# scale"); update that table together with these numbers.
FULL_SEED0 = {
    "states": 6274,
    "transitions": 15584,
    "immediate": 1289,
    "operable": 14295,
    "components": 3658,
}


def test_full_scale_ssm_totals_are_within_five_percent_of_the_paper():
    p = dashboard_probability()
    got = dict.fromkeys(FULL_SEED0, 0)
    for job in plan_devices(SCALES["full"], 0):
        logic = device_logic(job.category, job.device_id, 0, dashboard_p=p)
        got["components"] += len(logic.components)
        for sdef in logic.machine["states"].values():
            got["states"] += 1
            for comp, trans in sdef["on"].items():
                got["transitions"] += len(trans)
                got["immediate" if comp == "immediate" else "operable"] += len(trans)
    assert got == FULL_SEED0
    for key, paper in PAPER.items():
        assert abs(got[key] / paper - 1) < 0.05, (key, got[key], paper)
