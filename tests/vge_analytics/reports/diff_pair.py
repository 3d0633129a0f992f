"""The hand-worked pair of runs of `vge diff` and the Side by side page (the table of
tests/vge_analytics/reports/test_diff.py says what each episode is): runs A and B on copies of the
kettle_c task, B also on `only-b`, run C only on `only-c`."""

from __future__ import annotations

import json
from pathlib import Path

from ..conftest import HAND, replay_to, write_bench, write_run

LID_OPEN = "Action: Push(coord=[480, 90], params=[1])"
LID_CLOSE = "Action: Push(coord=[480, 90], params=[0])"
POWER_ON = "Action: Push(coord=[500, 850], params=[1])"
WAIT = "Action: Timed_wait()"
OUTSIDE = "Action: Push(coord=[1200, 90], params=[0])"
TO_FRONT = "Action: Switch_view(params=[front])"


def _outputs(*actions: str) -> list[dict]:
    return [{"output": f"Thinking: next.\n{a}"} for a in actions]


def build_hand_pair(root: Path) -> Path:
    """Write the bench and the runs A, B, C under `root` and replay them into `root/out`."""
    doc = json.loads((HAND / "kettle_c_parse_multigoal_chain.json").read_text())
    full = doc["episode"]["steps"]
    optimal = _outputs(LID_OPEN, LID_CLOSE, POWER_ON, WAIT)
    swapped = [*full[:2], full[4], full[3], full[2], *full[5:]]
    a = {
        "same": full,
        "prefix": full,
        "longer": full[:5],
        "view": full,
        "clean": full,
        "swapped": full,
        "late": optimal,
    }
    b = {
        "same": full,
        "prefix": full[:2],
        "longer": full,
        "view": [*full[:2], *_outputs(TO_FRONT)],
        "clean": optimal,
        "swapped": swapped,
        "late": [*optimal[:1], *_outputs(OUTSIDE), *optimal[1:]],
        "only-b": full,
    }
    ids = [*b, "only-c"]
    tasks = [{**doc["task"], "episode_id": i} for i in ids]
    bench = write_bench(root, [doc], tasks)

    def run(run_id: str, logs: dict[str, list]) -> Path:
        header = {"run_id": run_id, "model": f"model-{run_id}", "agent_kind": "vlm"}
        return write_run(root, header, [{"episode_id": k, "steps": v} for k, v in logs.items()])

    runs = [run("A", a), run("B", b), run("C", {"only-c": full})]
    return replay_to(root / "out", runs, bench)
