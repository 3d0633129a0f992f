"""Physical proportions and colours: the per-category numbers the layout draws from."""

from __future__ import annotations

# Nominal body size (X width, Y depth, Z height) in cm; each device varies around it.
BODY_DIMS: dict[str, tuple[float, float, float]] = {
    "AirFryer": (30.0, 36.0, 34.0),
    "AirPurifier": (32.0, 24.0, 58.0),
    "CarKey": (3.6, 1.6, 7.4),
    "CoffeeMachine": (26.0, 40.0, 36.0),
    "DigitalAlarmClock": (15.0, 7.0, 8.5),
    "DigitalCamera": (12.0, 5.5, 7.5),
    "ElectricFan": (38.0, 30.0, 62.0),
    "ElectricKettle": (17.0, 17.0, 25.0),
    "ElectricToothbrush": (3.2, 3.2, 22.0),
    "FilmCamera": (14.0, 6.5, 9.0),
    "Flashlight": (4.2, 4.2, 18.0),
    "HairDryer": (26.0, 9.0, 24.0),
    "Heater": (46.0, 20.0, 60.0),
    "Humidifier": (22.0, 22.0, 32.0),
    "Lamp": (24.0, 24.0, 46.0),
    "Landline": (22.0, 18.0, 10.0),
    "Lighter": (3.0, 1.6, 7.2),
    "MechanicalAlarmClock": (12.0, 6.0, 14.0),
    "Microwave": (50.0, 38.0, 30.0),
    "PowerBank": (7.0, 2.2, 14.0),
    "Razor": (5.5, 4.5, 16.0),
    "RiceCooker": (30.0, 30.0, 27.0),
    "ThermometerGun": (5.0, 13.0, 16.0),
    "Vacuum": (26.0, 22.0, 100.0),
    "WashingMachine": (60.0, 60.0, 85.0),
    "WeighingScale": (30.0, 30.0, 3.0),
}

DEFAULT_DIMS_BY_SIZE: dict[str, tuple[float, float, float]] = {
    "handheld": (5.0, 3.0, 12.0),
    "small": (15.0, 12.0, 18.0),
    "medium": (35.0, 30.0, 35.0),
    "large": (60.0, 60.0, 85.0),
}

# How big a component of each size class is, relative to the smaller side of its face,
# further scaled by the device size (controls are small on a washing machine's face).
SIZE_FRACTION = {"tiny": 0.13, "small": 0.19, "medium": 0.27, "large": 0.62}
DEVICE_SCALE = {"handheld": 1.0, "small": 0.82, "medium": 0.64, "large": 0.5}

# Width / height of a component's outline on its main face, per kind (None: chosen per part).
KIND_PROPORTION: dict[str, float] = {
    "button": 1.0,
    "touch_pad": 1.3,
    "key": 1.2,
    "trigger": 0.6,
    "shutter_button": 1.0,
    "knob": 1.0,
    "dial": 1.0,
    "wheel": 1.0,
    "ring": 1.0,
    "crank": 1.0,
    "lens": 1.0,
    "slider": 2.8,
    "switch": 0.7,
    "rocker": 0.65,
    "lever": 2.6,
    "door": 0.9,
    "lid": 1.2,
    "cover": 1.2,
    "drawer": 1.5,
    "basket": 1.4,
    "tank": 0.9,
    "tray": 1.8,
    "cap": 1.0,
    "head": 1.0,
    "nozzle": 1.0,
    "attachment": 1.3,
    "port": 1.7,
    "plug": 0.8,
    "cable": 0.8,
    "handle": 3.0,
    "grip": 0.5,
    "handset": 2.6,
    "body": 0.6,
    "platform": 1.2,
    "blade": 1.6,
}
ROUND_KINDS = frozenset({"knob", "dial", "wheel", "ring", "crank", "lens", "shutter_button", "cap"})
ORIENTED_KINDS = frozenset({"slider", "handle", "lever", "handset"})

BODY_COLORS: tuple[tuple[int, int, int], ...] = (
    (236, 236, 232),  # white
    (44, 46, 52),  # black
    (188, 192, 198),  # silver
    (176, 40, 44),  # red
    (238, 226, 200),  # cream
    (92, 98, 108),  # graphite
    (60, 104, 160),  # blue
    (126, 160, 130),  # sage
)
ACCENT_COLORS: tuple[tuple[int, int, int], ...] = (
    (220, 60, 50),
    (40, 130, 220),
    (250, 180, 40),
    (60, 170, 90),
    (150, 90, 200),
    (30, 30, 30),
    (240, 240, 240),
)
BACKGROUNDS: tuple[tuple[int, int, int], ...] = (
    (250, 250, 250),
    (242, 244, 247),
    (246, 243, 238),
    (236, 240, 236),
)


def darker(color: tuple[int, int, int], amount: float = 0.25) -> tuple[int, int, int]:
    return tuple(max(0, round(c * (1.0 - amount))) for c in color)  # type: ignore[return-value]


def lighter(color: tuple[int, int, int], amount: float = 0.25) -> tuple[int, int, int]:
    return tuple(min(255, round(c + (255 - c) * amount)) for c in color)  # type: ignore[return-value]


def luminance(color: tuple[int, int, int]) -> float:
    r, g, b = color
    return 0.299 * r + 0.587 * g + 0.114 * b


def ink_on(color: tuple[int, int, int]) -> tuple[int, int, int]:
    """Black or white text, whichever reads on `color`."""
    return (20, 20, 20) if luminance(color) > 140 else (245, 245, 245)
