"""Fixtures for the analytics tests: small benchmarks, runs and their replay output.

`hand_out` is built from the hand-worked replay cases (`tests/data/hand_worked/`): a bench
directory with their SSMs and tasks, two runs (the kettle cases a-g as run `kettle-vlm`, the
dashboard cases a-e as run `oven-human`), and the replay output directory of those runs,
written by `replay.replay_runs`.

`pair_out` is a constructed pair of runs for `compare`: ten copies of the kettle_c task
played by run A and run B with either the full (successful) kettle_c log or its first two
steps (the log ends after goal 1), so the success pattern and the error counts are known.

`clustered_out` is the statistics' hand-worked case: the kettle_c task on three devices
(copies of the kettle, `kettle_1` to `kettle_3`) with two episodes each, played by run A,
run B and two more seeds of B (`CLUSTERED_SUCCESS` says who solves which episode).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
LOGS = ROOT / "logs"
DATA = Path(__file__).resolve().parents[1] / "data"
HAND = DATA / "hand_worked"

KETTLE_CASES = (
    "kettle_a_axonometric_errors",
    "kettle_b_danger_repetitive_budget",
    "kettle_c_parse_multigoal_chain",
    "kettle_d_local_budget",
    "kettle_e_log_ended",
    "kettle_f_error_goal_fractional_lambda",
    "kettle_g_reset_chain",
)
OVEN_CASES = (
    "dashboard_a_active_unlock",
    "dashboard_b_passive_unlock",
    "dashboard_c_fault_late_switch",
    "dashboard_d_dyn_copt_validity",
    "dashboard_e_neutral_wait",
)

KETTLE_RUN = {
    "run_id": "kettle-vlm",
    "model": "model-k",
    "agent_kind": "vlm",
    "lambda": 5,
    "meta": {"history": "full", "perturbation": "none"},
}
OVEN_RUN = {
    "run_id": "oven-human",
    "model": "model-o",
    "agent_kind": "human",
    "lambda": 5,
    "meta": {"history": "3", "perturbation": "blur"},
}


def _case(name: str) -> dict:
    return json.loads((HAND / f"{name}.json").read_text())


def _ssm_path(name: str) -> Path:
    for base in (HAND, DATA):
        if (base / name).exists():
            return base / name
    raise FileNotFoundError(name)


def _write_jsonl(path: Path, rows: list[dict]) -> None:
    path.write_text("".join(json.dumps(r) + "\n" for r in rows))


def write_bench(root: Path, cases: list[dict], tasks: list[dict] | None = None) -> Path:
    bench = root / "bench"
    (bench / "ssm").mkdir(parents=True)
    for doc in cases:
        target = bench / "ssm" / f"{doc['device_id']}.json"
        if not target.exists():
            shutil.copyfile(_ssm_path(doc["ssm"]), target)
    _write_jsonl(bench / "tasks.jsonl", tasks if tasks is not None else [d["task"] for d in cases])
    return bench


def write_run(root: Path, header: dict, episodes: list[dict]) -> Path:
    run = root / "runs" / header["run_id"]
    run.mkdir(parents=True)
    (run / "run.json").write_text(json.dumps(header))
    _write_jsonl(run / "episodes.jsonl", episodes)
    return run


def replay_to(out: Path, run_dirs: list[Path], bench: Path) -> Path:
    """Replay runs into OUT with the replay engine's writer (PROTOCOL §7 layout)."""
    import replay

    replay.replay_runs([str(r) for r in run_dirs], str(bench), str(out), progress=False)
    return out


def _build_hand(root: Path) -> dict:
    kettle = [_case(n) for n in KETTLE_CASES]
    oven = [_case(n) for n in OVEN_CASES]
    bench = write_bench(root, kettle + oven)
    runs = [
        write_run(root, KETTLE_RUN, [d["episode"] for d in kettle]),
        write_run(root, OVEN_RUN, [d["episode"] for d in oven]),
    ]
    out = replay_to(root / "out", runs, bench)
    return {"root": root, "bench": bench, "runs": runs, "out": out}


@pytest.fixture(scope="session")
def hand(tmp_path_factory) -> dict:
    """{'root', 'bench', 'runs', 'out'} of the hand-worked runs (built once per session)."""
    return _build_hand(tmp_path_factory.mktemp("hand"))


@pytest.fixture(scope="session")
def hand_out(hand) -> Path:
    return hand["out"]


# ---------------------------------------------------------------------------- compare pair

PAIR_SUCCESS_A = {0, 1}
PAIR_SUCCESS_B = {1, 2, 3, 4, 5, 6}
PAIR_N = 10


def _build_pair(root: Path) -> dict:
    doc = _case("kettle_c_parse_multigoal_chain")
    full = doc["episode"]["steps"]
    short = full[:2]
    tasks = []
    for i in range(PAIR_N + 1):
        task = dict(doc["task"])
        task["episode_id"] = f"ep{i:02d}"
        tasks.append(task)
    bench = write_bench(root, [doc], tasks)

    def episodes(successes: set[int], ids: range) -> list[dict]:
        return [
            {"episode_id": f"ep{i:02d}", "steps": full if i in successes else short} for i in ids
        ]

    run_a = write_run(
        root,
        {"run_id": "A", "model": "gemini-sim", "agent_kind": "vlm", "lambda": 2},
        episodes(PAIR_SUCCESS_A, range(PAIR_N)),
    )
    # B also played ep10, which A did not: it must be left out of the comparison.
    run_b = write_run(
        root,
        {"run_id": "B", "model": "human-sim", "agent_kind": "human", "lambda": 2},
        episodes(PAIR_SUCCESS_B | {PAIR_N}, range(PAIR_N + 1)),
    )
    out = replay_to(root / "out", [run_a, run_b], bench)
    return {"root": root, "bench": bench, "runs": [run_a, run_b], "out": out}


@pytest.fixture(scope="session")
def pair(tmp_path_factory) -> dict:
    return _build_pair(tmp_path_factory.mktemp("pair"))


@pytest.fixture(scope="session")
def pair_out(pair) -> Path:
    return pair["out"]


# ---------------------------------------------------------------------------- bundled sample


@pytest.fixture(scope="session")
def sample_out(tmp_path_factory) -> Path:
    """The bundled sample (`logs/`: every category, every simulated profile) replayed."""
    runs = sorted(p for p in (LOGS / "runs").iterdir() if (p / "run.json").exists())
    assert runs, "logs/runs holds no run: the bundled sample is missing"
    return replay_to(tmp_path_factory.mktemp("sample") / "out", runs, LOGS / "bench")


# ---------------------------------------------------------------------- clustered (3 x 2)

CLUSTERED_EPISODES = (
    ("e1", "kettle_1"),
    ("e2", "kettle_1"),
    ("e3", "kettle_2"),
    ("e4", "kettle_2"),
    ("e5", "kettle_3"),
    ("e6", "kettle_3"),
)
CLUSTERED_SUCCESS: dict[str, tuple[int, ...]] = {
    # episodes:  e1 e2 e3 e4 e5 e6
    "A": (1, 0, 1, 1, 0, 0),
    "B": (1, 1, 0, 1, 1, 1),
    "B-seed1": (1, 0, 0, 1, 0, 1),
    "B-seed2": (0, 1, 0, 1, 1, 0),
}
"""Who solves which episode of `clustered_out`; B and its two seeds form a group of three
runs (run.json differs only in `meta.seed`), A a group of one."""


def _build_clustered(root: Path) -> dict:
    doc = _case("kettle_c_parse_multigoal_chain")
    full = doc["episode"]["steps"]
    bench = root / "bench"
    (bench / "ssm").mkdir(parents=True)
    tasks = []
    for episode_id, device_id in CLUSTERED_EPISODES:
        target = bench / "ssm" / f"{device_id}.json"
        if not target.exists():
            shutil.copyfile(_ssm_path(doc["ssm"]), target)
        tasks.append({**doc["task"], "episode_id": episode_id, "device_id": device_id})
    _write_jsonl(bench / "tasks.jsonl", tasks)
    runs = []
    for run_id, solved in CLUSTERED_SUCCESS.items():
        seed = {"B-seed1": 1, "B-seed2": 2}.get(run_id)
        header = {
            "run_id": run_id,
            "model": "model-a" if run_id == "A" else "model-b",
            "agent_kind": "vlm",
            "lambda": 2,
            "meta": {"history": "full"} | ({"seed": seed} if seed is not None else {}),
        }
        episodes = [
            {"episode_id": e, "steps": full if s else full[:2]}
            for (e, _), s in zip(CLUSTERED_EPISODES, solved, strict=True)
        ]
        runs.append(write_run(root, header, episodes))
    return {"bench": bench, "runs": runs, "out": replay_to(root / "out", runs, bench)}


@pytest.fixture(scope="session")
def clustered_out(tmp_path_factory) -> Path:
    return _build_clustered(tmp_path_factory.mktemp("clustered"))["out"]
