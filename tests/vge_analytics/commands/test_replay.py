"""`vge replay` runs with one OpenBLAS thread in each of its processes (numpy starts a
thread per core otherwise, which spins after it starts and the replay never uses), set before
numpy is first imported so that it takes effect; a value the user set is kept. Checked in a
fresh interpreter, where nothing has imported numpy yet."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

LOGS = Path(__file__).parents[3] / "logs"

PROBE = """
import json, os, sys
import vge_analytics.commands.replay as command
from vge_analytics.cli import main
seen = {{}}
set_it = command.one_blas_thread
def probe():
    seen["numpy_before"] = "numpy" in sys.modules
    set_it()
command.one_blas_thread = probe
code = main(["replay", {run!r}, "--bench", {bench!r}, "--out", {out!r}, "--no-progress"])
import numpy  # noqa: F401  (imported by the replay)
seen["code"] = code
seen["threads"] = os.environ.get("OPENBLAS_NUM_THREADS")
print(json.dumps(seen))
"""


def _replayed(tmp_path: Path, env: dict[str, str]) -> dict:
    run = sorted(p for p in (LOGS / "runs").iterdir() if p.is_dir())[0]
    code = PROBE.format(run=str(run), bench=str(LOGS / "bench"), out=str(tmp_path / "out"))
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=300, env=env
    )
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.splitlines()[-1])


def test_the_replay_sets_one_blas_thread_before_numpy_loads(tmp_path: Path) -> None:
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    seen = _replayed(tmp_path, env)
    assert seen == {"numpy_before": False, "code": seen["code"], "threads": "1"}
    assert seen["code"] in (0, 2)


def test_a_thread_count_the_user_set_is_kept(tmp_path: Path) -> None:
    seen = _replayed(tmp_path, {**os.environ, "OPENBLAS_NUM_THREADS": "3"})
    assert seen["threads"] == "3"
