"""UCSM + catalog -> one device's SSM (paper format + PROTOCOL §1.2 extensions), and back.

`instantiate_device` runs the logical half (`_logic`), decides what the layout needs
(which views each component is visible in, whether the device has a dashboard), lays the
device out (`_layout`) and writes the bboxes and dashboard regions into the SSM.
`layout_input_from_ssm` recovers the layout input from a written SSM, so the renderer can
draw exactly the device the SSM describes.
"""

from __future__ import annotations

import json
import random
from dataclasses import dataclass

from replay import DASHBOARD, STANDARD_VIEWS
from replay.semantics import BACK, FRONT, LEFT, RIGHT, VIEWS

from ._catalog import PAPER_DEVICE_COUNTS, available_categories, load_catalog
from ._geometry import (
    Geometry,
)
from ._layout import LayoutError, LayoutInput, layout, logical_form
from ._logic import NON_COMPONENTS, DeviceLogic, instantiate_logic
from ._rng import rng_for

PAPER_DASHBOARDS = 144
"""Devices with a dashboard view in the paper (7,888 views = 968 x 8 + 144)."""
EXTRA_FACE_KEEP = 1.0
"""Chance that a component is annotated in each of its secondary faces (the first always)."""
CURVED_SIDE_SHARE = 0.8
"""On a cylindrical body, chance that a control listed on one side sits off-centre, where the
curved surface shows it in the neighbouring side view too (and is annotated there)."""
_NEXT_SIDE = {
    FRONT: (RIGHT, LEFT),
    RIGHT: (BACK, FRONT),
    BACK: (LEFT, RIGHT),
    LEFT: (FRONT, BACK),
}
_LISTED_RANK = {v: i for i, v in enumerate(VIEWS)}
"""A component's boxes are written in the order of `VIEWS` (the planner's `VIEW_ORDER` puts the
dashboard before the axonometric views: another concept)."""


@dataclass(frozen=True, slots=True)
class SyntheticDevice:
    """One generated device."""

    device_id: str
    category: str
    ssm: dict
    """The SSM as written to `ssm/<device_id>.json`."""
    geometry: Geometry
    logic: DeviceLogic


def dashboard_probability(categories: tuple[str, ...] | None = None) -> float:
    """Chance that a device of a dashboard category has a dashboard, so that a full-scale
    benchmark has about as many dashboards as the paper."""
    cats = available_categories() if categories is None else categories
    eligible = sum(PAPER_DEVICE_COUNTS.get(c, 0) for c in cats if load_catalog(c).dashboard)
    return 1.0 if eligible <= 0 else min(1.0, PAPER_DASHBOARDS / eligible)


def device_logic(
    category: str, device_id: str, seed: int, *, dashboard_p: float | None = None
) -> DeviceLogic:
    """The logical half of `instantiate_device` alone (the SSM without geometry): the same
    states and transitions, without the cost of a layout."""
    return _logic_half(category, device_id, rng_for(seed, "device", device_id), dashboard_p)[0]


def _logic_half(
    category: str, device_id: str, rng: random.Random, dashboard_p: float | None
) -> tuple[DeviceLogic, bool]:
    """(the device's logic, whether it wants a dashboard), drawn from `rng`."""
    catalog = load_catalog(category)
    p = dashboard_probability() if dashboard_p is None else dashboard_p
    wants_dashboard = catalog.dashboard and rng.random() < p
    force: frozenset[str] = frozenset()
    if wants_dashboard:
        # A device with a dashboard has a control panel: at least two of its controls.
        on_panel = sorted(c for c, spec in catalog.components.items() if spec.on_dashboard)
        force = frozenset(rng.sample(on_panel, min(2, len(on_panel))))
    return instantiate_logic(category, device_id, rng, force=force), wants_dashboard


def instantiate_device(
    category: str, device_id: str, seed: int, *, dashboard_p: float | None = None
) -> SyntheticDevice:
    """Generate one device of `category`; deterministic in (category, device_id, seed)."""
    rng = rng_for(seed, "device", device_id)
    catalog = load_catalog(category)
    logic, wants_dashboard = _logic_half(category, device_id, rng, dashboard_p)
    panel_parts = [c for c in logic.components if catalog.components[c].on_dashboard]
    has_dashboard = wants_dashboard and len(panel_parts) >= 1
    views: dict[str, tuple[str, ...]] = {}
    for comp in logic.components:
        spec = catalog.components[comp]
        if has_dashboard and spec.on_dashboard:
            views[comp] = (DASHBOARD,)
        else:
            views[comp] = _face_subset(spec.faces, rng)
            draw = rng.random()
            side = views[comp][0]
            if (
                catalog.body.lower().startswith("cylind")
                and len(views[comp]) == 1
                and side in _NEXT_SIDE
                and spec.size != "large"
                and draw < CURVED_SIDE_SHARE
            ):
                views[comp] = (side, _NEXT_SIDE[side][0 if draw < CURVED_SIDE_SHARE / 2 else 1])
    machine = logic.machine
    logical = logical_form(machine["name"], machine["initial_state"], machine["states"])
    for _ in range(4 * len(views) + 2):
        inp = LayoutInput(device_id, category, logical, views, has_dashboard)
        try:
            geometry = layout(inp)
            break
        except LayoutError as exc:
            # A component that does not fit everywhere is annotated in fewer views (its
            # last secondary face goes), as an annotator would skip a hidden one.
            comp = exc.component
            if comp is None and has_dashboard:
                has_dashboard = False
                views = {
                    c: (catalog.components[c].faces[0],) if v == (DASHBOARD,) else v
                    for c, v in views.items()
                }
            elif comp in views and len(views[comp]) > 1:
                views = {**views, comp: views[comp][:-1]}
            else:
                raise
    else:
        raise LayoutError(f"{device_id}: no layout found")
    return SyntheticDevice(device_id, category, _assemble(logic, geometry), geometry, logic)


def _face_subset(faces: tuple[str, ...], rng: random.Random) -> tuple[str, ...]:
    keep = [faces[0]]
    for face in faces[1:]:
        if rng.random() < EXTRA_FACE_KEEP:
            keep.append(face)
    return tuple(keep)


def _assemble(logic: DeviceLogic, geometry: Geometry) -> dict:
    bboxes = geometry.bboxes()
    states: dict[str, dict] = {}
    for sname, sdef in logic.machine["states"].items():
        on: dict[str, list[dict]] = {}
        for comp, trans in sdef["on"].items():
            out = []
            for t in trans:
                item = {
                    "next_state": t["next_state"],
                    "transition_description": t["transition_description"],
                }
                if comp not in NON_COMPONENTS:
                    item["bbox"] = [
                        {"coordinate": coord, "view": view}
                        for view, coord in sorted(
                            bboxes[comp].items(), key=lambda kv: _LISTED_RANK[kv[0]]
                        )
                    ]
                    item["atomic_action"] = t["atomic_action"]
                    item["parameter"] = list(t["parameter"])
                out.append(item)
            on[comp] = out
        entry: dict = {"description": sdef["description"], "on": on}
        if sdef.get("is_error"):
            entry["is_error"] = True
        states[sname] = entry
    ssm: dict = {
        "name": logic.machine["name"],
        "device_id": logic.device_id,
        "category": logic.category,
        "initial_state": logic.machine["initial_state"],
        "views": list(STANDARD_VIEWS),
    }
    regions = geometry.regions()
    if regions:
        ssm["dashboard"] = {"regions": regions}
    ssm["states"] = states
    return ssm


# ------------------------------------------------------------------------------ reading


def layout_input_from_ssm(ssm, device_id: str) -> LayoutInput | None:
    """The layout input of an SSM record (`replay.StateMachine`) the generator wrote, or None
    when the SSM cannot be one of ours (unknown components, views off their faces)."""
    category = ssm.category or ssm.name
    try:
        catalog = load_catalog(category)
    except FileNotFoundError:
        return None
    seen: dict[str, set[str]] = {}
    for sdef in ssm.states.values():
        for comp, trans in sdef.on.items():
            if comp in NON_COMPONENTS:
                continue
            bucket = seen.setdefault(comp, set())
            for t in trans:
                bucket.update(b.view.lower() for b in t.bbox)
    views: dict[str, tuple[str, ...]] = {}
    for comp, vs in seen.items():
        spec = catalog.components.get(comp)
        if spec is None:
            return None
        if vs == {DASHBOARD}:
            views[comp] = (DASHBOARD,)
            continue
        ordered = tuple(f for f in spec.faces if f in vs)
        extra = vs - set(ordered)
        if extra and len(ordered) == 1 and catalog.body.lower().startswith("cylind"):
            if len(extra) != 1 or next(iter(extra)) not in _NEXT_SIDE.get(ordered[0], ()):
                return None
            ordered = ordered + tuple(extra)
        if set(ordered) != vs or not ordered or ordered[0] != spec.faces[0]:
            return None
        views[comp] = ordered
    has_dashboard = bool(ssm.dashboard is not None and ssm.dashboard.regions)
    return LayoutInput(
        ssm.device_id or device_id,
        category,
        logical_form(ssm.name, ssm.initial_state, ssm.states),
        views,
        has_dashboard,
    )


def geometry_matches(ssm, geometry: Geometry) -> bool:
    """True when every bbox and dashboard region of the SSM is the one the layout computes."""
    bboxes = geometry.bboxes()
    for sdef in ssm.states.values():
        for comp, trans in sdef.on.items():
            if comp in NON_COMPONENTS:
                continue
            want = bboxes.get(comp)
            if want is None:
                return False
            for t in trans:
                got = {b.view.lower(): [round(float(c)) for c in b.coordinate] for b in t.bbox}
                if got != want:
                    return False
    regions = [
        {"view": r.view.lower(), "coordinate": [round(float(c)) for c in r.coordinate]}
        for r in (ssm.dashboard.regions if ssm.dashboard is not None else [])
    ]
    return regions == geometry.regions()


def scene_of(ssm, device_id: str) -> Geometry | None:
    """The layout that produced a loaded SSM (`replay.StateMachine`), or None when the SSM is
    not exactly what the layout gives (hand-made, edited, or from another layout version)."""
    inp = layout_input_from_ssm(ssm, device_id)
    if inp is None:
        return None
    try:
        geometry = layout(inp)
    except LayoutError:
        return None
    return geometry if geometry_matches(ssm, geometry) else None


def dump_ssm(ssm: dict) -> str:
    """The SSM as JSON text: one transition per line (readable, compact, deterministic)."""

    def enc(value) -> str:
        return json.dumps(value, ensure_ascii=False, separators=(", ", ": "))

    lines = ["{"]
    head = [k for k in ssm if k != "states"]
    for key in head:
        lines.append(f"  {enc(key)}: {enc(ssm[key])},")
    lines.append('  "states": {')
    state_items = list(ssm["states"].items())
    for si, (sname, sdef) in enumerate(state_items):
        lines.append(f"    {enc(sname)}: {{")
        lines.append(f'      "description": {enc(sdef["description"])},')
        if sdef.get("is_error"):
            lines.append('      "is_error": true,')
        lines.append('      "on": {')
        comps = list(sdef["on"].items())
        for ci, (comp, trans) in enumerate(comps):
            lines.append(f"        {enc(comp)}: [")
            for ti, t in enumerate(trans):
                comma = "," if ti < len(trans) - 1 else ""
                lines.append(f"          {enc(t)}{comma}")
            lines.append("        ]" + ("," if ci < len(comps) - 1 else ""))
        lines.append("      }")
        lines.append("    }" + ("," if si < len(state_items) - 1 else ""))
    lines.append("  }")
    lines.append("}")
    return "\n".join(lines) + "\n"
