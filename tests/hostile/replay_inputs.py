"""Hostile inputs for the replay, generated (never stored): benchmarks with machines long,
deep or wide, and runs whose records are huge, deep, endless or oddly named. Shared by
`tests/hostile/test_replay_input.py` (small sizes) and `benchmarks/bench_hostile.py` (the
sizes of docs/REPLAY.md, "Hostile input")."""

from __future__ import annotations

import gzip
import json
from collections.abc import Iterable, Iterator
from pathlib import Path

BUTTON = {"coordinate": [400, 400, 200, 200, 1000, 1000], "view": "front"}
"""Every button of the generated machines: the middle fifth of the front view."""
PRESS = "Thinking: the button.\nAction: Press(coord=[500, 500])"
"""A step that presses it."""


def _press(next_state: str) -> dict:
    return {
        "next_state": next_state,
        "transition_description": f"now {next_state}",
        "atomic_action": "press",
        "bbox": [BUTTON],
    }


def line_ssm(states: int) -> dict:
    """S0 -> S1 -> ... -> S{states-1}, one press each: a plan as long as the machine."""
    names = [f"S{i}" for i in range(states)]
    return {
        "name": "Line",
        "initial_state": names[0],
        "states": {
            name: {"on": {"button": [_press(names[i + 1])]} if i + 1 < states else {}}
            for i, name in enumerate(names)
        },
    }


def chain_ssm(length: int) -> dict:
    """Off -press-> C1 -immediate-> C2 ... -immediate-> C{length}; C{length} -press-> Off:
    one press enters `length` states."""
    chain = [f"C{i}" for i in range(1, length + 1)]
    states: dict[str, dict] = {"Off": {"on": {"button": [_press(chain[0])]}}}
    for here, there in zip(chain, chain[1:], strict=False):
        states[here] = {"on": {"immediate": [{"next_state": there}]}}
    states[chain[-1]] = {"on": {"button": [_press("Off")]}}
    return {"name": "Chain", "initial_state": "Off", "states": states}


def write_bench(root: Path, ssms: dict[str, dict], tasks: Iterable[dict]) -> Path:
    """BENCH/ssm/<device>.json and BENCH/tasks.jsonl."""
    (root / "ssm").mkdir(parents=True, exist_ok=True)
    for device, ssm in ssms.items():
        (root / "ssm" / f"{device}.json").write_text(json.dumps(ssm))
    with open(root / "tasks.jsonl", "w") as fh:
        for task in tasks:
            fh.write(json.dumps(task) + "\n")
    return root


def task(episode_id: str, device: str, goal: str) -> dict:
    return {"episode_id": episode_id, "device_id": device, "goals": [goal]}


def episode(episode_id: str, steps: int = 1, output: str = PRESS) -> bytes:
    """One line of episodes.jsonl (without its newline)."""
    record = {"episode_id": episode_id, "steps": [{"output": output}] * steps}
    return json.dumps(record).encode()


def write_run(root: Path, lines: Iterable[bytes], *, run_id: str = "run", gz: bool = False) -> Path:
    """RUN/run.json and RUN/episodes.jsonl[.gz], one line per record (each with its newline)."""
    root.mkdir(parents=True, exist_ok=True)
    header = {"run_id": run_id, "model": "m", "agent_kind": "scripted"}
    (root / "run.json").write_text(json.dumps(header))
    name = "episodes.jsonl.gz" if gz else "episodes.jsonl"
    with gzip.open(root / name, "wb", compresslevel=1) if gz else open(root / name, "wb") as fh:
        for line in lines:
            fh.write(line + b"\n")
    return root


def padded(episode_id: str, size: int) -> bytes:
    """An episode line of `size` bytes: one press whose Thinking text fills the rest."""
    bare = episode(episode_id, output="Thinking: .\nAction: Press(coord=[500, 500])")
    filler = "x" * (size - len(bare))
    return episode(episode_id, output=f"Thinking: {filler}.\nAction: Press(coord=[500, 500])")


def nested(depth: int) -> str:
    """JSON text of `depth` nested arrays."""
    return "[" * depth + "]" * depth


def deep_step(episode_id: str, depth: int) -> bytes:
    """A good record but for `depth` nested arrays in one step (its level 4 on)."""
    doc = json.dumps({"episode_id": episode_id, "steps": [{"output": PRESS, "x": 0}]})
    return doc.replace('"x": 0', '"x": ' + nested(depth)).encode()


def zeros(size: int, block: int = 1 << 20) -> Iterator[bytes]:
    """`size` bytes of '0' with no newline, in blocks (one line, never held whole)."""
    while size > 0:
        yield b"0" * min(block, size)
        size -= block


def append_gzip(path: Path, chunk: bytes, times: int) -> None:
    """Append `chunk` `times` over to a .gz file, as gzip members compressed once: gigabytes
    inflated from a file of kilobytes, written in milliseconds."""
    member = gzip.compress(chunk, compresslevel=9, mtime=0)
    with open(path, "ab") as fh:
        for _ in range(times):
            fh.write(member)
