"""A metric file whose query would take the machine (issue 25): its numerator,
`sum(length(repeat(episode_id, 20000000)))`, is valid and additive, but each value it builds
is 400 MB that DuckDB's memory limit does not account for (it drove `vge metrics` to 22.5 GB
before). Every command that evaluates a metric file ends with one line naming the file and
the bound, and the dashboard's query for it ends in its own capped process, the server's
own memory unchanged.

Each runs as a process under an address-space bound (`tests.bounded.run_bounded`), 4 GB: a
regression that lifts the process cap is stopped there, and fails the assertion on its peak
resident memory (under 1.5 GB), instead of taking the machine.

The OUT: two runs of the bundled sample (`logs/`), replayed once for the module.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

import replay
from tests.bounded import run_bounded

from ..vge_analytics.metrics.metric_files import metric_text

ROOT = Path(__file__).resolve().parents[2]
LOGS = ROOT / "logs"
RUNS = ("sim-vlm-a", "sim-vlm-b")
VGE = [sys.executable, "-m", "vge_analytics.cli"]
GB = 1024**3
LIMIT = "512MB"
REPEAT = "sum(length(repeat(episode_id, 20000000)))"


@pytest.fixture(scope="module")
def out(tmp_path_factory) -> Path:
    where = tmp_path_factory.mktemp("bounds") / "out"
    replay.replay_runs(
        [str(LOGS / "runs" / r) for r in RUNS], str(LOGS / "bench"), str(where), progress=False
    )
    return where


@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("metrics") / "mine"
    root.mkdir()
    (root / "repeat.sql").write_text(metric_text("Repeat", REPEAT, "count(*)"), encoding="utf-8")
    return root


def _memory_line(
    folder: Path,
    hint: str = " (--memory-limit sets the limit)",
    bound: str = "512 MB in memory, 1 GB on disk",
) -> str:
    return (
        f"{folder / 'repeat.sql'}: the query of this metric file needed more memory than its "
        f"limit ({bound}) and was stopped{hint}"
    )


def _default_bound(out: Path) -> str:
    """The bound a command takes without `--memory-limit`: sized from OUT (512 MB and half
    of its tables' bytes; 2 runs of the sample: about 1 MB)."""
    from vge_analytics.store import SqlLimits, sized_memory_limit

    limits = SqlLimits.make(memory=sized_memory_limit(out, None))
    assert 512 * 1024**2 < limits.memory < 520 * 1024**2, limits.memory
    return limits.describe()


COMMANDS = {
    "metrics": ["metrics", "{out}"],
    "compare": ["compare", "{out}", *RUNS],
    "compare --all": ["compare", "{out}", "--all", "--metric", "Repeat"],
    "rescore": ["rescore", "{out}"],
    "sweep": ["sweep", "{out}", "--lambdas", "2,3", "--metrics", "Repeat"],
    "power": ["power", "{out}", *RUNS, "--metric", "Repeat"],
}


@pytest.mark.parametrize("name", list(COMMANDS))
def test_a_metric_file_past_the_memory_bound_ends_in_one_line(out: Path, folder: Path, name):
    args = [a.format(out=out) for a in COMMANDS[name]]
    done = run_bounded(
        [*VGE, *args, "--metrics-dir", str(folder), "--memory-limit", LIMIT],
        address_space=4 * GB,
        timeout=180,
    )
    assert done.returncode == 1, done.stderr
    assert done.stderr == f"error: {_memory_line(folder)}\n"
    assert done.peak_memory < 1.5 * GB, done.peak_memory


@pytest.mark.parametrize("name", ["metrics", "compare", "rescore", "sweep"])
def test_with_default_options_too(out: Path, folder: Path, name):
    """Without `--memory-limit` the bound is sized from OUT: the same one line, under 1.5 GB."""
    args = [a.format(out=out) for a in COMMANDS[name]]
    done = run_bounded(
        [*VGE, *args, "--metrics-dir", str(folder)], address_space=4 * GB, timeout=180
    )
    assert done.returncode == 1, done.stderr
    assert done.stderr == f"error: {_memory_line(folder, bound=_default_bound(out))}\n"
    assert done.peak_memory < 1.5 * GB, done.peak_memory


def test_the_command_goes_on_within_its_bounds_without_the_file(out: Path, folder: Path):
    """The cap is around each query: the built-in metrics of the same process are computed."""
    done = run_bounded(
        [*VGE, "metrics", str(out), "-f", "csv", "--memory-limit", LIMIT], address_space=4 * GB
    )
    assert done.returncode == 0, done.stderr
    rows = done.stdout_head.decode().splitlines()
    assert [row.split(",")[0] for row in rows[1:3]] == list(RUNS)


SCRIPT_SERVER = """
import json, os, resource, sys
sys.path.insert(0, sys.argv[3])
import vge_analytics as va
from app import _data
from tests.bounded import TreeMemory

def own_peak():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024

if __name__ == "__main__":
    out, folder = sys.argv[1], sys.argv[2]
    # As `vge app` passes its --sql-memory-limit to the pages (app/_data.py).
    argv = ["--sql-memory-limit", sys.argv[4], "--query-timeout", "120"]
    with _data.query_bounds(argv):
        va.metrics(out)  # the server's own working size
    before = own_peak()
    errors = {}
    with TreeMemory(os.getpid()) as tree, _data.query_bounds(argv):
        for page, call in (
            ("Leaderboard", lambda: va.metrics(out, metrics_dir=folder)),
            ("Significance", lambda: va.compare(out, "sim-vlm-a", "sim-vlm-b", metrics_dir=folder)),
            # a sweep's tables are in the server's memory: handed to the query process
            ("Budgets", lambda: va.sweep(out, [2], metrics=["Repeat"], metrics_dir=folder)),
        ):
            try:
                call()
                errors[page] = None
            except va.AnalyticsError as exc:
                errors[page] = str(exc)
        sr = va.metrics(out, metrics=["SR"])["SR"].to_list()  # the server's own, after
    print(json.dumps({
        "errors": errors, "sr": sr, "grew": own_peak() - before, "child": tree.largest_below(),
    }))
"""


@pytest.mark.parametrize("given", [LIMIT, None], ids=["512MB", "default"])
def test_the_dashboard_runs_a_metric_file_in_a_capped_query_process(
    out: Path, folder: Path, tmp_path: Path, given: str | None
):
    from vge_analytics.store import sized_memory_limit

    script = tmp_path / "server.py"  # a file: the forkserver's children import it by path
    script.write_text(SCRIPT_SERVER)
    limit = str(sized_memory_limit(out, given))  # what `vge app` passes on
    done = run_bounded(
        [sys.executable, str(script), str(out), str(folder), str(ROOT), limit],
        address_space=6 * GB,  # the server and its forkserver; each query process caps itself
        timeout=180,
    )
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout_head)
    bound = _default_bound(out) if given is None else "512 MB in memory, 1 GB on disk"
    line = _memory_line(folder, hint="", bound=bound)
    assert report["errors"] == {"Leaderboard": line, "Significance": line, "Budgets": line}
    assert len(report["sr"]) == 2
    # The server did not hold the values; the query process stopped at its cap.
    assert report["grew"] < 200 * 1024**2, report["grew"]
    assert 0 < report["child"] < 1.5 * GB, report["child"]
    assert done.peak_memory < 1.5 * GB, done.peak_memory
