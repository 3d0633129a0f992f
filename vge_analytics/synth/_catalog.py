"""The hand-written category data: UCSMs (paper format) and component catalogs.

`data/ucsm/<Category>.json` is a Universal Category State Machine with `atomic_action` /
`parameter` hints on every real transition; `data/catalog/<Category>.json` says what each
component looks like (kind, label, faces it is visible from, size, whether it is optional or
sits on the dashboard), the device's body and size, and natural goal phrases per state.
A category is *available* when both files exist, so new categories are picked up as they land.
"""

from __future__ import annotations

import functools
import json
from pathlib import Path

import msgspec

from replay.io import UCSM_DIR

DATA_DIR = Path(__file__).resolve().parent / "data"
UCSM_TEMPLATES = DATA_DIR / UCSM_DIR
"""The category templates, laid out as a benchmark's `ucsm/` folder."""
CATALOG_DIR = DATA_DIR / "catalog"

PAPER_DEVICE_COUNTS: dict[str, int] = {
    "CoffeeMachine": 72,
    "DigitalAlarmClock": 71,
    "Lighter": 63,
    "Microwave": 59,
    "WashingMachine": 55,
    "MechanicalAlarmClock": 54,
    "WeighingScale": 49,
    "Heater": 48,
    "Lamp": 46,
    "ElectricKettle": 44,
    "ElectricFan": 41,
    "AirFryer": 36,
    "Flashlight": 34,
    "FilmCamera": 32,
    "Razor": 29,
    "DigitalCamera": 28,
    "HairDryer": 27,
    "Humidifier": 27,
    "Landline": 23,
    "PowerBank": 23,
    "CarKey": 22,
    "Vacuum": 21,
    "AirPurifier": 20,
    "RiceCooker": 19,
    "ElectricToothbrush": 14,
    "ThermometerGun": 11,
}
"""Devices per category in the paper (Table "Category-wise distribution", 968 in total)."""


class ComponentSpec(msgspec.Struct, frozen=True, forbid_unknown_fields=False):
    """How one component of a category looks and where it sits."""

    kind: str
    """Visual kind: button, knob, dial, slider, door, port, handle, ..."""
    label: str
    """Printed text, or `icon:<name>` for a pictogram, or empty."""
    faces: tuple[str, ...]
    """Orthographic faces it is visible from (1-3); two adjacent faces put it on their edge."""
    required: bool
    """Every device of the category has it; optional ones are pruned per device."""
    size: str
    """tiny, small, medium or large (relative to the face it sits on)."""
    on_dashboard: bool = False
    """Sits on the control panel that becomes the zoomed dashboard view on large devices."""


class Catalog(msgspec.Struct, frozen=True, forbid_unknown_fields=False):
    """Everything the generator and the renderer need to know about a category."""

    category: str
    size: str
    """Device size class: handheld, small, medium, large."""
    body: str
    """Body shape name (box, cylinder, ...); unknown names are drawn as a rounded box."""
    dashboard: bool
    """Devices of this category may have a dashboard (zoomed control panel)."""
    components: dict[str, ComponentSpec]
    goal_phrases: dict[str, tuple[str, ...]]
    """State -> natural instructions that reach it, never naming a component."""
    device_noun: str


_catalog_decoder = msgspec.json.Decoder(Catalog)


def available_categories() -> tuple[str, ...]:
    """Categories with both a UCSM and a catalog file, sorted by name."""
    ucsms = {p.stem for p in UCSM_TEMPLATES.glob("*.json")}
    catalogs = {p.stem for p in CATALOG_DIR.glob("*.json")}
    return tuple(sorted(ucsms & catalogs))


@functools.cache
def load_catalog(category: str) -> Catalog:
    """The component catalog of a category (cached)."""
    return _catalog_decoder.decode((CATALOG_DIR / f"{category}.json").read_bytes())


@functools.cache
def _ucsm_text(category: str) -> str:
    return (UCSM_TEMPLATES / f"{category}.json").read_text(encoding="utf-8")


def load_ucsm(category: str) -> dict:
    """A fresh copy of the category's UCSM as plain JSON data (paper format)."""
    return json.loads(_ucsm_text(category))


def data_digest(category: str) -> str:
    """sha256 of the category's UCSM and catalog bytes (part of the image cache key)."""
    import hashlib

    h = hashlib.sha256()
    h.update((UCSM_TEMPLATES / f"{category}.json").read_bytes())
    h.update(b"\0")
    h.update((CATALOG_DIR / f"{category}.json").read_bytes())
    return h.hexdigest()


def is_known_category(category: str) -> bool:
    name = f"{category}.json"
    return (UCSM_TEMPLATES / name).exists() and (CATALOG_DIR / name).exists()
