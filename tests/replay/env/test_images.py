"""The environment's view cache: every view is decoded once while it fits, the least recently
shown is dropped past the memory bound, and what is shown never depends on the cache."""

from __future__ import annotations

import numpy as np

from replay.env._images import ViewImages
from replay.semantics import Machine


class _Device:
    def __init__(self, device_id: str) -> None:
        self.device_id = device_id


def test_views_are_decoded_once_and_the_least_recent_is_dropped() -> None:
    asked: list[tuple[str, str]] = []

    def source(machine: Machine, view: str) -> None:
        asked.append((machine.device_id, view))

    one_view = 8 * 6 * 3
    images = ViewImages(source, 8, 6, cache_bytes=2 * one_view)  # room for two views
    kettle, fan = _Device("kettle"), _Device("fan")
    shown = [images.array(d, v) for d, v in [(kettle, "front"), (fan, "top"), (kettle, "front")]]
    assert asked == [("kettle", "front"), ("fan", "top")]  # across devices, no reload
    images.array(fan, "back")  # a third view: kettle/front was shown after fan/top, fan/top goes
    images.array(kettle, "front")
    images.array(fan, "top")
    assert asked == [("kettle", "front"), ("fan", "top"), ("fan", "back"), ("fan", "top")]
    assert shown[0].shape == (6, 8, 3) and np.array_equal(shown[0], shown[2])
    shown[0][:] = 0  # callers own their copy
    assert not np.array_equal(images.array(kettle, "front"), shown[0])
