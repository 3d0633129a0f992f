"""Invariants of the hand-written synthetic VGEBench data (UCSMs and component catalogs).

`vge_analytics/synth/data/ucsm/<Category>.json` holds the 26 Universal Category State Machines
in the paper's format (with `atomic_action`/`parameter` hints on every real transition) and
`vge_analytics/synth/data/catalog/<Category>.json` the component catalog the instantiation and
rendering code reads. This module only uses the standard library: it must stay fast and
independent of the engine.
"""

from __future__ import annotations

import itertools
import json
import re
from collections import deque
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
DATA = ROOT / "vge_analytics" / "synth" / "data"
UCSM_DIR = DATA / "ucsm"
CATALOG_DIR = DATA / "catalog"
KETTLE_LISTING = ROOT / "tests" / "data" / "kettle_ucsm.json"

CATEGORIES = (
    "AirFryer",
    "AirPurifier",
    "CarKey",
    "CoffeeMachine",
    "DigitalAlarmClock",
    "DigitalCamera",
    "ElectricFan",
    "ElectricKettle",
    "ElectricToothbrush",
    "FilmCamera",
    "Flashlight",
    "HairDryer",
    "Heater",
    "Humidifier",
    "Lamp",
    "Landline",
    "Lighter",
    "MechanicalAlarmClock",
    "Microwave",
    "PowerBank",
    "Razor",
    "RiceCooker",
    "ThermometerGun",
    "Vacuum",
    "WashingMachine",
    "WeighingScale",
)
DASHBOARD_REQUIRED = {"WashingMachine", "Microwave", "CoffeeMachine", "AirFryer"}

NON_COMPONENTS = ("immediate", "timed_wait")
ACTIONS = ("press", "rotate", "push", "pull", "grasp")
ORTHO_FACES = {"front", "back", "left", "right", "top", "bottom"}
SIZES = {"tiny", "small", "medium", "large"}
DEVICE_SIZES = {"handheld", "small", "medium", "large"}

# Totals over the 26 UCSMs (paper: 302 states, 1,206 transitions, 234 component types).
STATES_RANGE = (272, 332)
TRANSITIONS_RANGE = (1085, 1327)
COMPONENTS_RANGE = (210, 258)

# What a component looks like decides how it can be operated (physical consistency).
KIND_ACTIONS = {
    "button": {"press", "push"},
    "touch_pad": {"press"},
    "key": {"press"},
    "trigger": {"press"},
    "shutter_button": {"press"},
    "knob": {"rotate", "press", "pull", "push"},
    "dial": {"rotate", "press"},
    "wheel": {"rotate"},
    "ring": {"rotate"},
    "crank": {"rotate"},
    "lens": {"rotate", "push", "pull"},
    "slider": {"push"},
    "switch": {"push", "press"},
    "rocker": {"press", "push"},
    "lever": {"push", "pull", "press"},
    "door": {"pull", "push"},
    "lid": {"pull", "push"},
    "cover": {"pull", "push"},
    "drawer": {"pull", "push"},
    "basket": {"pull", "push"},
    "tank": {"pull", "push"},
    "tray": {"pull", "push"},
    "cap": {"pull", "push", "rotate"},
    "head": {"pull", "push", "rotate"},
    "nozzle": {"pull", "push", "rotate"},
    "attachment": {"pull", "push"},
    "port": {"push", "pull"},
    "plug": {"push", "pull"},
    "cable": {"push", "pull"},
    "handle": {"grasp", "pull", "push"},
    "grip": {"grasp"},
    "handset": {"grasp"},
    "body": {"grasp"},
    "platform": {"press", "push"},
    "blade": {"pull", "push"},
}

PARAM_RE = re.compile(r"^[1-9][0-9]*$")


def _load(directory: Path, category: str) -> dict | None:
    path = directory / f"{category}.json"
    if not path.exists():
        return None
    with open(path, encoding="utf-8") as fh:
        return json.load(fh)


class _Files(dict):
    """Category -> parsed file; a missing file fails the test that needs it."""

    def __missing__(self, category):
        pytest.fail(f"missing data file for {category}")


UCSMS = _Files({c: d for c in CATEGORIES if (d := _load(UCSM_DIR, c)) is not None})
CATALOGS = _Files({c: d for c in CATEGORIES if (d := _load(CATALOG_DIR, c)) is not None})


def _transitions(ucsm: dict):
    for state, body in ucsm["states"].items():
        for component, trans in body["on"].items():
            for t in trans:
                yield state, component, t


def _is_error(ucsm: dict, state: str) -> bool:
    return state == "Error" or bool(ucsm["states"][state].get("is_error"))


def _has_immediate(ucsm: dict, state: str) -> bool:
    return "immediate" in ucsm["states"][state]["on"]


def _timed_results(ucsm: dict) -> set[str]:
    return {t["next_state"] for _, c, t in _transitions(ucsm) if c == "timed_wait"}


def _goalable(ucsm: dict) -> set[str]:
    """States that can be goals: all but error states and pure settling (immediate) states;
    the result states of timed processes stay goal-able even when they settle immediately."""
    timed = _timed_results(ucsm)
    return {
        s
        for s in ucsm["states"]
        if not _is_error(ucsm, s) and (not _has_immediate(ucsm, s) or s in timed)
    }


def _edges(ucsm: dict, allowed: set[str] | None = None) -> dict[str, set[str]]:
    """Adjacency of the machine, keeping only special components and `allowed` ones."""
    adj: dict[str, set[str]] = {s: set() for s in ucsm["states"]}
    for state, component, t in _transitions(ucsm):
        if allowed is not None and component not in NON_COMPONENTS and component not in allowed:
            continue
        adj[state].add(t["next_state"])
    return adj


def _reach(adj: dict[str, set[str]], start: str) -> set[str]:
    seen, todo = {start}, deque([start])
    while todo:
        s = todo.popleft()
        for n in adj[s]:
            if n not in seen:
                seen.add(n)
                todo.append(n)
    return seen


def _reverse(adj: dict[str, set[str]]) -> dict[str, set[str]]:
    rev: dict[str, set[str]] = {s: set() for s in adj}
    for s, ns in adj.items():
        for n in ns:
            rev[n].add(s)
    return rev


def _totals() -> dict[str, object]:
    per = {}
    for c in CATEGORIES:
        u = UCSMS[c]
        comps = {comp for _, comp, _ in _transitions(u) if comp not in NON_COMPONENTS}
        per[c] = (len(u["states"]), sum(1 for _ in _transitions(u)), len(comps))
    names = {comp for c in CATEGORIES for _, comp, _ in _transitions(UCSMS[c])} - set(
        NON_COMPONENTS
    )
    return {
        "states": sum(v[0] for v in per.values()),
        "transitions": sum(v[1] for v in per.values()),
        "components": sum(v[2] for v in per.values()),
        "distinct_component_names_global": len(names),
        "per_category": per,
    }


def test_all_files_present_and_no_extra():
    assert sorted(p.stem for p in UCSM_DIR.glob("*.json")) == sorted(CATEGORIES)
    assert sorted(p.stem for p in CATALOG_DIR.glob("*.json")) == sorted(CATEGORIES)


@pytest.mark.parametrize("category", CATEGORIES)
def test_ucsm_structure(category):
    u = UCSMS[category]
    assert set(u) >= {"name", "initial_state", "states"}
    assert u["name"] == category
    assert u["initial_state"] in u["states"], "unknown initial_state"
    assert not _has_immediate(u, u["initial_state"]), "initial state must be stable"
    for state, body in u["states"].items():
        assert re.fullmatch(r"[A-Z][A-Za-z0-9]*", state), f"state name {state!r}"
        assert isinstance(body.get("description"), str) and body["description"].strip(), state
        on = body.get("on")
        assert isinstance(on, dict) and on, f"{state}: no transitions"
        for component, trans in on.items():
            assert component in NON_COMPONENTS or re.fullmatch(r"[a-z][a-z0-9_]*", component), (
                component
            )
            assert isinstance(trans, list) and trans, f"{state}.{component}: empty list"
            for t in trans:
                where = f"{category}:{state}.{component}"
                assert t["next_state"] in u["states"], f"{where}: dangling {t['next_state']}"
                assert t["next_state"] != state, f"{where}: self-loop"
                assert isinstance(t.get("transition_description"), str), where
                assert t["transition_description"].strip(), where


def _check_params(action: str, params: list) -> str | None:
    if not isinstance(params, list) or not all(isinstance(p, str) for p in params):
        return "parameter must be a list of strings"
    if action == "press":
        return None if len(params) == 1 and params[0] in {"0", "1", "2"} else "press [0|1|2]"
    if action == "rotate":
        if len(params) != 2:
            return "rotate [direction, extent]"
        d, e = params
        if d not in {"0", "1", "*"}:
            return "rotate direction 0|1|*"
        if e != "*" and not PARAM_RE.match(e):
            return "rotate extent positive int or *"
        return None
    if action in {"push", "pull"}:
        ok = len(params) == 1 and params[0] in {"0", "1", "2", "3", "4"}
        return None if ok else f"{action} [0..4]"
    if action == "grasp":
        return None if len(params) == 1 and params[0] in {"0", "1"} else "grasp [0|1]"
    return f"unknown action {action}"


@pytest.mark.parametrize("category", CATEGORIES)
def test_actions_and_parameters(category):
    u = UCSMS[category]
    kinds = {n: c["kind"] for n, c in CATALOGS[category]["components"].items()}
    for state, body in u["states"].items():
        on = body["on"]
        if "immediate" in on:
            n = sum(len(v) for v in on.values())
            assert n == 1, (
                f"{category}:{state}: a state with `immediate` has exactly one transition"
            )
        if "timed_wait" in on:
            assert len(on["timed_wait"]) == 1, f"{category}:{state}: several timed_wait"
        for component, trans in on.items():
            seen = set()
            for t in trans:
                where = f"{category}:{state}.{component}"
                if component in NON_COMPONENTS:
                    assert "atomic_action" not in t and "parameter" not in t, where
                    continue
                action = t.get("atomic_action")
                assert action in ACTIONS, f"{where}: atomic_action {action!r}"
                err = _check_params(action, t.get("parameter"))
                assert err is None, f"{where}: {err} (got {t.get('parameter')})"
                key = (action, tuple(t["parameter"]))
                assert key not in seen, f"{where}: duplicate {key}"
                seen.add(key)
                kind = kinds.get(component)
                assert kind in KIND_ACTIONS, f"{where}: unknown kind {kind!r}"
                assert action in KIND_ACTIONS[kind], f"{where}: {action} on a {kind}"


@pytest.mark.parametrize("category", CATEGORIES)
def test_immediate_chains_terminate(category):
    u = UCSMS[category]
    for start in u["states"]:
        s, seen = start, set()
        while _has_immediate(u, s):
            assert s not in seen, f"{category}: immediate cycle through {s}"
            seen.add(s)
            s = u["states"][s]["on"]["immediate"][0]["next_state"]


@pytest.mark.parametrize("category", CATEGORIES)
def test_reachability_both_ways(category):
    u = UCSMS[category]
    adj = _edges(u)
    init = u["initial_state"]
    fwd = _reach(adj, init)
    assert fwd == set(u["states"]), f"{category}: unreachable {sorted(set(u['states']) - fwd)}"
    back = _reach(_reverse(adj), init)
    assert back == set(u["states"]), (
        f"{category}: no way back from {sorted(set(u['states']) - back)}"
    )


@pytest.mark.parametrize("category", CATEGORIES)
def test_error_states(category):
    u = UCSMS[category]
    for state, body in u["states"].items():
        if _is_error(u, state):
            on = body["on"]
            assert list(on) == ["immediate"] and len(on["immediate"]) == 1, state
            assert on["immediate"][0]["next_state"] == u["initial_state"], state
            assert body["description"] == "Error operation state"
            assert any(t["next_state"] == state for _, _, t in _transitions(u))


@pytest.mark.parametrize("category", CATEGORIES)
def test_pruning_keeps_machine_usable(category):
    """Whatever subset of optional components a device lacks, the states still reachable
    from the initial state can all get back to it, and some goals remain."""
    u, cat = UCSMS[category], CATALOGS[category]
    comps = cat["components"]
    optional = sorted(n for n, c in comps.items() if not c["required"])
    assert len(optional) <= 10, "too many optional components to check exhaustively"
    goalable = _goalable(u)
    init = u["initial_state"]
    for k in range(len(optional) + 1):
        for missing in itertools.combinations(optional, k):
            allowed = set(comps) - set(missing)
            adj = _edges(u, allowed)
            kept = _reach(adj, init)
            sub = {s: adj[s] & kept for s in kept}
            back = _reach(_reverse(sub), init)
            assert back == kept, f"{category} without {missing}: stuck in {sorted(kept - back)}"
            goals = (kept & goalable) - {init}
            assert len(goals) >= 2, f"{category} without {missing}: only goals {goals}"


@pytest.mark.parametrize("category", CATEGORIES)
def test_catalog(category):
    cat, u = CATALOGS[category], UCSMS[category]
    assert cat["category"] == category
    assert cat["size"] in DEVICE_SIZES
    assert isinstance(cat["body"], str) and cat["body"]
    assert isinstance(cat["dashboard"], bool)
    if category in DASHBOARD_REQUIRED:
        assert cat["dashboard"], f"{category} must have a dashboard"
    assert isinstance(cat["device_noun"], str) and cat["device_noun"]
    used = {comp for _, comp, _ in _transitions(u) if comp not in NON_COMPONENTS}
    assert set(cat["components"]) == used, (
        f"catalog-only {sorted(set(cat['components']) - used)}, "
        f"ucsm-only {sorted(used - set(cat['components']))}"
    )
    n_dash = 0
    for name, c in cat["components"].items():
        assert c["kind"] in KIND_ACTIONS, f"{name}: kind {c['kind']!r}"
        assert isinstance(c["label"], str), name
        faces = c["faces"]
        assert 1 <= len(faces) <= 3 and set(faces) <= ORTHO_FACES, f"{name}: faces {faces}"
        assert len(set(faces)) == len(faces), name
        assert isinstance(c["required"], bool), name
        assert c["size"] in SIZES, name
        if c.get("on_dashboard"):
            assert cat["dashboard"], f"{name}: on_dashboard without a dashboard"
            n_dash += 1
    if cat["dashboard"]:
        assert n_dash >= 3, f"{category}: a dashboard needs several small controls"
    assert any(c["required"] for c in cat["components"].values())


def _words(text: str) -> str:
    return " " + re.sub(r"[^a-z0-9]+", " ", text.lower()) + " "


@pytest.mark.parametrize("category", CATEGORIES)
def test_goal_phrases(category):
    cat, u = CATALOGS[category], UCSMS[category]
    phrases = cat["goal_phrases"]
    goalable = _goalable(u)
    missing = goalable - set(phrases)
    assert not missing, f"{category}: goal-able states without phrases {sorted(missing)}"
    names = [n.replace("_", " ") for n in cat["components"]]
    seen: dict[str, str] = {}
    for state, texts in phrases.items():
        assert state in u["states"], f"{category}: phrases for unknown state {state}"
        assert not _is_error(u, state), f"{category}: phrases for an error state"
        assert 2 <= len(texts) <= 4, f"{category}:{state}: 2-4 phrases"
        for text in texts:
            assert isinstance(text, str) and text.strip() and text == text.strip()
            assert text[0].isupper(), f"{category}:{state}: {text!r}"
            for name in names:
                assert f" {name} " not in _words(text), (
                    f"{category}:{state}: {text!r} names the component {name!r}"
                )
            assert text.lower() not in seen, f"{category}: {text!r} used twice"
            seen[text.lower()] = state


def test_kettle_follows_paper_listing():
    with open(KETTLE_LISTING, encoding="utf-8") as fh:
        paper = json.load(fh)
    ours = json.loads(json.dumps(UCSMS["ElectricKettle"]))
    for _, _, t in _transitions(ours):
        t.pop("atomic_action", None)
        t.pop("parameter", None)
    assert ours == paper
    real = [(c, t) for _, c, t in _transitions(UCSMS["ElectricKettle"]) if c not in NON_COMPONENTS]
    assert all("atomic_action" in t for _, t in real)
    by = {
        (s, c, t["next_state"]): (t["atomic_action"], t["parameter"])
        for s, c, t in _transitions(UCSMS["ElectricKettle"])
        if c not in NON_COMPONENTS
    }
    assert by[("Standby", "power_button", "Boiling")] == ("push", ["1"])
    assert by[("Boiling", "power_button", "Standby")] == ("push", ["0"])
    assert by[("Standby", "lid_release_button", "LidOpen")] == ("push", ["1"])
    assert by[("LidOpen", "lid_release_button", "Standby")] == ("push", ["0"])


def test_totals_within_targets():
    t = _totals()
    per = "\n".join(
        f"  {c:22s} states={s:3d} transitions={n:4d} components={k:3d}"
        for c, (s, n, k) in t["per_category"].items()
    )
    msg = (
        f"totals: states={t['states']} transitions={t['transitions']} "
        f"components={t['components']} (distinct names across categories: "
        f"{t['distinct_component_names_global']})\n{per}"
    )
    assert STATES_RANGE[0] <= t["states"] <= STATES_RANGE[1], msg
    assert TRANSITIONS_RANGE[0] <= t["transitions"] <= TRANSITIONS_RANGE[1], msg
    assert COMPONENTS_RANGE[0] <= t["components"] <= COMPONENTS_RANGE[1], msg
