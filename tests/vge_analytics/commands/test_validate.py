"""`vge validate`: the paper's kettle passes; bad SSMs, tasks and logs fail with clear lines."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

from vge_analytics.cli import main

DATA = Path(__file__).resolve().parents[2] / "data"
LOGS = Path(__file__).resolve().parents[3] / "logs"


def _kettle_bench(root: Path, tasks: list[dict]) -> Path:
    (root / "ssm").mkdir(parents=True)
    shutil.copyfile(DATA / "kettle_ssm.json", root / "ssm" / "kettle.json")  # verbatim
    (root / "ucsm").mkdir()
    shutil.copyfile(DATA / "kettle_ucsm.json", root / "ucsm" / "ElectricKettle.json")
    (root / "tasks.jsonl").write_text("".join(json.dumps(t) + "\n" for t in tasks))
    return root


GOOD_TASKS = [
    {
        "episode_id": "k1",
        "device_id": "kettle",
        "goals": ["Boiling"],
        "instructions": ["Boil the water"],
    },
    {
        "episode_id": "k2",
        "device_id": "kettle",
        "goals": ["LidOpen", "Standby", "Boiling"],
        "initial_view": "front_top",
        "c_opt": [2, 1, 1],
    },
]


def test_paper_kettle_passes(tmp_path: Path, capsys) -> None:
    bench = _kettle_bench(tmp_path / "bench", GOOD_TASKS)
    assert main(["validate", str(bench)]) == 0
    assert "OK 1 SSM(s), 2 task(s), 0 run(s): 0 error(s), 0 warning(s)" in capsys.readouterr().out


def test_every_problem_is_reported(tmp_path: Path, capsys) -> None:
    bench = _kettle_bench(
        tmp_path / "bench",
        GOOD_TASKS
        + [
            {"episode_id": "k3", "device_id": "kettle", "goals": ["Standby"]},
            {"episode_id": "k4", "device_id": "toaster", "goals": ["On"]},
            {"episode_id": "k5", "device_id": "kettle", "goals": ["Boiling"], "c_opt": [3]},
        ],
    )
    with open(bench / "tasks.jsonl", "a") as fh:
        fh.write('{"episode_id": 7}\n')
    ssm = json.loads((DATA / "kettle_ssm.json").read_text())
    ssm["states"]["Standby"]["on"]["power_button"][0]["next_state"] = "Boil"
    (bench / "ssm" / "broken.json").write_text(json.dumps(ssm, indent=1))
    run = tmp_path / "run"
    run.mkdir()
    (run / "run.json").write_text(json.dumps({"run_id": "r", "model": "m", "agent_kind": "vlm"}))
    (run / "episodes.jsonl").write_text(
        '{"episode_id": "k1", "steps": []}\n{"episode_id": "nope", "steps": []}\nnot json\n'
    )
    assert main(["validate", str(bench), str(run)]) == 1
    out = capsys.readouterr().out
    lines = [line for line in out.splitlines() if line.startswith(("error", "warning"))]
    expected = [
        f"{bench}/ssm/broken.json [state 'Standby', component 'power_button', transition 0]: dangling next_state 'Boil'",
        f"{bench}/tasks.jsonl:6: Expected str, got int - at $.episode_id",
        f"{bench}/tasks.jsonl:3 [episode 'k3']: goal 1 'Standby' is the state in which it becomes current",
        f"{bench}/tasks.jsonl:4 [episode 'k4']: unknown device 'toaster'",
        f"{bench}/tasks.jsonl:5 [episode 'k5']: stated c_opt [3] differs from the computed [1]",
        f"{run}/episodes.jsonl:2 [episode 'nope']: unknown episode id",
        f"{run}/episodes.jsonl:3: JSON is malformed",
    ]
    for needle in expected:
        assert any(needle in line for line in lines), (needle, lines)
    assert len(lines) == len(expected)
    assert "FAILED 2 SSM(s), 5 task(s), 1 run(s): 6 error(s), 1 warning(s)" in out


def test_bundled_sample_validates(capsys) -> None:
    runs = sorted(str(p) for p in (LOGS / "runs").iterdir())
    assert main(["validate", str(LOGS / "bench"), *runs]) == 0
    assert "0 error(s)" in capsys.readouterr().out
