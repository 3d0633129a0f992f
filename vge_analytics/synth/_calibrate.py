"""Re-derive the per-category pruning rates of `_logic.CATEGORY_PRUNING`.

For each category, a grid over (optional component keep rate, function drop rate) is searched
for the pair whose mean number of operable transitions per device is closest to the paper's
per-category action count (Table "atomic actions" / devices), with a small preference for
about 3.8 components per device. Devices of dashboard categories keep two panel controls with
the dashboard probability, as `instantiate_device` does.

    python -m vge_analytics.synth._calibrate      # prints the table to paste into _logic.py
"""

from __future__ import annotations

from replay.semantics import IMMEDIATE

from ._catalog import PAPER_DEVICE_COUNTS, available_categories, load_catalog
from ._instantiate import dashboard_probability
from ._logic import instantiate_logic
from ._rng import rng_for

PAPER_ACTIONS: dict[str, int] = {
    "AirFryer": 1909,
    "AirPurifier": 274,
    "CarKey": 147,
    "CoffeeMachine": 1332,
    "DigitalAlarmClock": 530,
    "DigitalCamera": 244,
    "ElectricFan": 1265,
    "ElectricKettle": 308,
    "ElectricToothbrush": 176,
    "FilmCamera": 330,
    "Flashlight": 261,
    "HairDryer": 1266,
    "Heater": 456,
    "Humidifier": 202,
    "Lamp": 92,
    "Landline": 141,
    "Lighter": 430,
    "MechanicalAlarmClock": 311,
    "Microwave": 2161,
    "PowerBank": 146,
    "Razor": 200,
    "RiceCooker": 241,
    "ThermometerGun": 25,
    "Vacuum": 146,
    "WashingMachine": 1271,
    "WeighingScale": 540,
}
"""Operable transitions (press, pull, push, rotate, grasp, timed_wait) per category."""

KEEP_GRID = (0.0, 0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.85, 1.0)
DROP_GRID = (0.0, 0.15, 0.3, 0.45, 0.6, 0.75, 0.9)
TARGET_COMPONENTS = 3712 / 968


def measure(category: str, keep: float, drop: float, n: int = 50) -> tuple[float, float]:
    """(mean operable transitions, mean components) per device at these rates."""
    catalog = load_catalog(category)
    p_dash = dashboard_probability()
    actions = components = 0
    for i in range(n):
        rng = rng_for("calibrate", category, i)
        force: frozenset[str] = frozenset()
        if catalog.dashboard and rng.random() < p_dash:
            panel = sorted(c for c, spec in catalog.components.items() if spec.on_dashboard)
            force = frozenset(rng.sample(panel, min(2, len(panel))))
        logic = instantiate_logic(
            category, f"{category}_{i}", rng, optional_keep=keep, function_drop=drop, force=force
        )
        for sdef in logic.machine["states"].values():
            for comp, trans in sdef["on"].items():
                if comp != IMMEDIATE:
                    actions += len(trans)
        components += len(logic.components)
    return actions / n, components / n


def calibrate(category: str, component_weight: float = 0.5) -> tuple[float, float]:
    target = PAPER_ACTIONS[category] / PAPER_DEVICE_COUNTS[category]
    best: tuple[float, float, float] | None = None
    for keep in KEEP_GRID:
        for drop in DROP_GRID:
            actions, components = measure(category, keep, drop)
            score = (
                abs(actions - target) / max(target, 1.0)
                + component_weight * abs(components - TARGET_COMPONENTS) / TARGET_COMPONENTS
            )
            if best is None or score < best[0]:
                best = (score, keep, drop)
    assert best is not None
    return best[1], best[2]


def main() -> None:
    for category in available_categories():
        if category in PAPER_ACTIONS:
            keep, drop = calibrate(category)
            print(f'    "{category}": ({keep}, {drop}),', flush=True)


if __name__ == "__main__":
    main()
