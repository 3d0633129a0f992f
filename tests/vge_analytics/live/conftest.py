"""A two-task kettle benchmark for the live runs (tests/data/kettle_ssm.json, no images), and
the same with 24 episodes (`many_tasks`).

`open-lid` (goal LidOpen, from the right view) needs one step: push the lid release button,
which the right view shows at x 427.48..534.35, y 73.05..109.99 on the 0..1000 scale.
`boil` (goal BoilingComplete, from the front) needs two: push the power button (front view,
x 704.71..856.91, y 697.59..753.10) with parameter 1, then wait (PROTOCOL §4.3: C_opt 1 and 2;
the geometry is worked out in tests/data/hand_worked/kettle_c_parse_multigoal_chain.json).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

DATA = Path(__file__).resolve().parents[2] / "data"

OPEN_LID = (
    "Thinking: The lid release button is at the top.\nAction: Push(coord=[480, 90], params=[1])"
)
MALFORMED = "Thinking: The lid release button.\nAction: Push(coord=[480, 90, params=[1])"
PUSH_POWER = "Thinking: The power switch.\nAction: Push(coord=[780, 725], params=[1])"
WAIT = "Thinking: The water is heating.\nAction: Timed_wait()"

TASKS = [
    {
        "episode_id": "open-lid",
        "device_id": "kettle",
        "goals": ["LidOpen"],
        "instructions": ["Open the lid."],
        "initial_view": "right",
    },
    {
        "episode_id": "boil",
        "device_id": "kettle",
        "goals": ["BoilingComplete"],
        "instructions": ["Boil the water."],
        "initial_view": "front",
    },
]


def write_kettle_bench(bench: Path) -> Path:
    """The two-task kettle benchmark, written at `bench`."""
    (bench / "ssm").mkdir(parents=True)
    shutil.copy(DATA / "kettle_ssm.json", bench / "ssm" / "kettle.json")
    (bench / "tasks.jsonl").write_text("".join(json.dumps(t) + "\n" for t in TASKS))
    return bench


@pytest.fixture
def kettle_bench(tmp_path: Path) -> Path:
    return write_kettle_bench(tmp_path / "bench")


@pytest.fixture
def many_tasks(kettle_bench: Path) -> Path:
    """24 episodes: 12 copies of each kettle task, interleaved (`open-lid-00`, `boil-00`,
    `open-lid-01`, ...)."""
    lines = [
        json.dumps({**task, "episode_id": f"{task['episode_id']}-{k:02d}"})
        for k in range(12)
        for task in TASKS
    ]
    (kettle_bench / "tasks.jsonl").write_text("\n".join(lines) + "\n")
    return kettle_bench
