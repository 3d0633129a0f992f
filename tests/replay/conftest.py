"""A tiny benchmark and runs built from the hand-worked cases (`tests/data/hand_worked/`).

`sample` (session-scoped, read-only) holds:
- `bench/`: the SSMs the cases use, PNG views of the kettle (`images/kettle/<view>.png`),
  and tasks: every case's task in `COPIES` copies
  (episode ids `<id>-c<k>`; one id with characters that need escaping in file names),
  plus `ghost-device` (no SSM) and `bad-task` (an unknown goal state) for quarantine tests;
- `runs/vlm/`: every episode, plain `.jsonl`; copy 1 records the expected feedback kind,
  state and view (no divergence); copy 2 records a wrong state on step 0 (one diverged
  step per episode) and timestamps;
- `runs/human/`: copy 0 only, gzipped, other meta facets, no lambda in run.json.
Tests that modify inputs copy them first (`copy_sample`).
"""

from __future__ import annotations

import gzip
import json
import shutil
from dataclasses import dataclass
from pathlib import Path

import pytest

DATA = Path(__file__).resolve().parent.parent / "data"
CASES = DATA / "hand_worked"
COPIES = 3
ODD_ID_SUFFIX = "-c0 #odd/id"  # needs percent-encoding as a file name


def _cases() -> list[dict]:
    out = []
    for path in sorted(CASES.glob("*.json")):
        doc = json.loads(path.read_text())
        if isinstance(doc, dict) and "expected" in doc:
            out.append(doc)
    return out


def _ssm_path(name: str) -> Path:
    for base in (CASES, DATA):
        if (base / name).exists():
            return base / name
    raise FileNotFoundError(name)


@dataclass(frozen=True)
class Sample:
    root: Path
    bench: Path
    vlm: Path
    human: Path
    episode_ids: list[str]  # of the vlm run, in file order
    steps_per_episode: dict[str, int]

    @property
    def runs(self) -> list[Path]:
        return [self.vlm, self.human]


def _episode_id(doc: dict, k: int) -> str:
    base = doc["task"]["episode_id"]
    if k == 0 and doc is _cases_cache[0]:
        return base + ODD_ID_SUFFIX
    return f"{base}-c{k}"


_cases_cache = _cases()


def _recorded_steps(doc: dict, k: int) -> list[dict]:
    steps = [dict(s) for s in doc["episode"]["steps"]]
    expected = doc["expected"]["steps"]
    if k == 1:
        for i, s in enumerate(steps):
            want = expected[str(i)]
            if not want["truncated"]:
                s["feedback"] = want["feedback_kind"]
                s["state"] = want["state_after"]
                s["view"] = want["view_after"]
    if k == 2:
        for i, s in enumerate(steps):
            s["timestamp"] = 1_700_000_000 + 2.5 * i
        if steps and not expected["0"]["truncated"]:
            steps[0]["state"] = "NotTheRealState"
    return steps


IMAGE_SIZE = (64, 48)
"""Kettle view images (other devices have none: MCAP without /camera)."""


def _write_images(directory: Path) -> None:
    from PIL import Image

    directory.mkdir(parents=True)
    views = ["front", "back", "left", "right", "top", "bottom", "front_top", "back_bottom"]
    for i, view in enumerate(views):
        Image.new("RGB", IMAGE_SIZE, (30 * i, 100, 200)).save(directory / f"{view}.png")


def write_lines(path: Path, lines: list[bytes]) -> None:
    data = b"".join(line + b"\n" for line in lines)
    path.write_bytes(gzip.compress(data, mtime=0) if path.suffix == ".gz" else data)


def build_sample(root: Path) -> Sample:
    bench = root / "bench"
    (bench / "ssm").mkdir(parents=True)
    devices: dict[str, Path] = {}
    for doc in _cases_cache:
        devices[doc["device_id"]] = _ssm_path(doc["ssm"])
    for device, path in sorted(devices.items()):
        shutil.copy(path, bench / "ssm" / f"{device}.json")

    _write_images(bench / "images" / "kettle")

    tasks: list[dict] = []
    vlm_lines: list[bytes] = []
    human_lines: list[bytes] = []
    ids: list[str] = []
    steps_per_episode: dict[str, int] = {}
    for k in range(COPIES):
        for doc in _cases_cache:
            eid = _episode_id(doc, k)
            tasks.append({**doc["task"], "episode_id": eid})
            line = json.dumps({"episode_id": eid, "steps": _recorded_steps(doc, k)}).encode()
            vlm_lines.append(line)
            ids.append(eid)
            steps_per_episode[eid] = len(doc["episode"]["steps"])
            if k == 0:
                human_lines.append(line)
    first = _cases_cache[0]["task"]
    tasks.append({**first, "episode_id": "ghost-device", "device_id": "toaster"})
    tasks.append({**first, "episode_id": "bad-task", "goals": ["NoSuchState"]})
    write_lines(bench / "tasks.jsonl", [json.dumps(t).encode() for t in tasks])

    vlm = root / "runs" / "vlm"
    vlm.mkdir(parents=True)
    (vlm / "run.json").write_text(
        json.dumps(
            {
                "run_id": "vlm-a",
                "model": "model-a",
                "agent_kind": "vlm",
                "lambda": 5,
                "meta": {"history": 3, "perturbation": "none", "notes": {"x": 1}},
            }
        )
    )
    write_lines(vlm / "episodes.jsonl", vlm_lines)

    human = root / "runs" / "human"
    human.mkdir(parents=True)
    (human / "run.json").write_text(
        json.dumps(
            {
                "run_id": "human-1",
                "model": "humans",
                "agent_kind": "human",
                "meta": {"history": "full", "participants": 7, "trained": True},
            }
        )
    )
    write_lines(human / "episodes.jsonl.gz", human_lines)
    return Sample(root, bench, vlm, human, ids, steps_per_episode)


@pytest.fixture(scope="session")
def sample(tmp_path_factory: pytest.TempPathFactory) -> Sample:
    return build_sample(tmp_path_factory.mktemp("sample"))


@pytest.fixture
def copy_sample(sample: Sample, tmp_path: Path) -> Sample:
    """A private, modifiable copy of the sample."""
    root = tmp_path / "inputs"
    shutil.copytree(sample.root, root)
    return Sample(
        root,
        root / "bench",
        root / "runs" / "vlm",
        root / "runs" / "human",
        list(sample.episode_ids),
        dict(sample.steps_per_episode),
    )


@pytest.fixture(scope="session")
def replayed(sample: Sample, tmp_path_factory: pytest.TempPathFactory):
    """The sample replayed once (both runs, MCAP on), for read-only checks."""
    import replay

    out = tmp_path_factory.mktemp("replayed") / "out"
    manifest = replay.replay_runs(
        sample.runs,
        sample.bench,
        out,
        mcap=True,
        progress=False,
        image_source=replay.BenchImages(str(sample.bench)),
    )
    return out, manifest


@pytest.fixture
def vge():
    """`vge`, every command registered (registering only some would leave the others out
    for the later tests of the same process: the app registers once)."""
    from vge_analytics import cli

    return cli.main
