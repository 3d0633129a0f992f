"""Comparisons refuse runs replayed against different benchmarks (issue 25): their episodes
share ids, not tasks. Before, `vge compare` and `vge diff` of two such runs reported their
common episodes and compared them.

The OUT: runs of the bundled sample (`logs/`) replayed against three benchmarks: the bundled
one (sim-vlm-a, sim-vlm-c), a copy whose first task says its instruction in other words
(sim-vlm-b: another tasks.jsonl), and a copy whose AirFryer_000 SSM is written out again with
indentation (sim-vlm-d: the same tasks, another SSM file).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

import replay
import vge_analytics as va
from vge_analytics.cli import main
from vge_analytics.store import Benchmark, benchmark_of, check_same_benchmark, open_store

LOGS = Path(__file__).resolve().parents[3] / "logs"
SHA = {
    "tasks": "b17ebc2751ca",  # logs/bench/tasks.jsonl
}


def _replay(out: Path, run: str, bench: Path) -> None:
    replay.replay_runs([str(LOGS / "runs" / run)], str(bench), str(out), progress=False)


@pytest.fixture(scope="module")
def benches(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("benches")
    reworded, ssm = root / "reworded", root / "ssm"
    shutil.copytree(LOGS / "bench", reworded)
    tasks = reworded / "tasks.jsonl"
    lines = tasks.read_text().splitlines(keepends=True)
    lines[0] = lines[0].replace("Choose 200 degrees", "Set 200 degrees")
    tasks.write_text("".join(lines))
    shutil.copytree(LOGS / "bench", ssm)
    machine = ssm / "ssm" / "AirFryer_000.json"
    machine.write_text(json.dumps(json.loads(machine.read_text()), indent=2))
    return {"bundled": LOGS / "bench", "reworded": reworded, "ssm": ssm}


@pytest.fixture(scope="module")
def out(benches, tmp_path_factory) -> Path:
    where = tmp_path_factory.mktemp("two") / "out"
    for run, bench in (
        ("sim-vlm-a", "bundled"),
        ("sim-vlm-b", "reworded"),
        ("sim-vlm-c", "bundled"),
        ("sim-vlm-d", "ssm"),
    ):
        _replay(where, run, benches[bench])
    return where


def _refusal(out: Path, benches, a: str, b: str, why: str) -> str:
    bench = {"sim-vlm-a": "bundled", "sim-vlm-b": "reworded", "sim-vlm-c": "bundled"}
    bench["sim-vlm-d"] = "ssm"
    where = {"bundled": str(LOGS / "bench")} | {
        k: str(v) for k, v in benches.items() if k != "bundled"
    }
    return (
        f"runs {a!r} and {b!r} of {out} were replayed against different benchmarks "
        f"({where[bench[a]]} and {where[bench[b]]}: {why}); their episodes share ids, not "
        "tasks, so they are not compared"
    )


def _tasks_digest(bench: Path) -> str:
    import hashlib

    return hashlib.sha256((bench / "tasks.jsonl").read_bytes()).hexdigest()[:12]


def test_the_manifest_tells_the_benchmarks_apart(out: Path, benches) -> None:
    store = open_store(out)
    a, b, c, d = (
        benchmark_of(store, r) for r in ("sim-vlm-a", "sim-vlm-b", "sim-vlm-c", "sim-vlm-d")
    )
    assert a.tasks is not None and a.tasks[:12] == SHA["tasks"] == _tasks_digest(LOGS / "bench")
    assert a.differs(c) is None
    assert (
        a.differs(b)
        == f"tasks.jsonl sha256 {SHA['tasks']} and {_tasks_digest(benches['reworded'])}"
    )
    assert d.tasks == a.tasks  # the same tasks; one SSM differs
    assert a.differs(d).startswith("the SSM of AirFryer_000: sha256 ")
    # What is not recorded cannot tell two benchmarks apart: not refused.
    assert Benchmark("x", None, {}).differs(b) is None
    assert benchmark_of(store, "not-a-run").differs(a) is None


def test_every_comparison_refuses_runs_of_two_benchmarks(out: Path, benches) -> None:
    line = _refusal(
        out,
        benches,
        "sim-vlm-a",
        "sim-vlm-b",
        f"tasks.jsonl sha256 {SHA['tasks']} and {_tasks_digest(benches['reworded'])}",
    )
    calls = {
        "compare": lambda **kw: va.compare(out, "sim-vlm-a", "sim-vlm-b", **kw),
        "compare_all": lambda **kw: va.compare_all(out, runs=["sim-vlm-a", "sim-vlm-b"], **kw),
        "diff": lambda **kw: va.diff(out, "sim-vlm-a", "sim-vlm-b", **kw),
        "power": lambda **kw: va.power_of_pair(out, "sim-vlm-a", "sim-vlm-b", **kw),
        "repeated": lambda **kw: va.repeated(
            out, runs=["sim-vlm-a", "sim-vlm-b"], group_by=["agent_kind"], **kw
        ),
    }
    for name, call in calls.items():
        with pytest.raises(va.DifferentBenchmarksError) as caught:
            call()
        assert str(caught.value) == line, name
        call(allow_different_benchmarks=True)  # when asked, compared as before
    # Each pair of the same benchmark is compared: 312 common episodes.
    assert va.compare(out, "sim-vlm-a", "sim-vlm-c").n_common == 312
    assert va.diff(out, "sim-vlm-a", "sim-vlm-c").rows.height == 312


def test_an_ssm_that_differs_is_a_different_benchmark(out: Path, benches) -> None:
    with pytest.raises(va.DifferentBenchmarksError) as caught:
        va.compare(out, "sim-vlm-a", "sim-vlm-d")
    assert f"({LOGS / 'bench'} and " + str(
        benches["ssm"]
    ) + ": the SSM of AirFryer_000: sha256 " in str(caught.value)
    # --all with every run: the first pair that differs is named.
    with pytest.raises(va.DifferentBenchmarksError, match="runs 'sim-vlm-a' and 'sim-vlm-b'"):
        va.compare_all(out)
    assert va.compare_all(out, runs=["sim-vlm-a", "sim-vlm-c"]).pairs.height == 1
    check_same_benchmark(open_store(out), ["sim-vlm-a", "sim-vlm-c", "sim-vlm-a"])


@pytest.mark.parametrize(
    "args",
    [
        ["compare", "{out}", "sim-vlm-a", "sim-vlm-b"],
        ["compare", "{out}", "--all"],
        ["diff", "{out}", "sim-vlm-a", "sim-vlm-b"],
        ["power", "{out}", "sim-vlm-a", "sim-vlm-b"],
        ["passk", "{out}", "--runs", "sim-vlm-a,sim-vlm-b", "--group-by", "agent_kind"],
    ],
    ids=["compare", "compare-all", "diff", "power", "passk"],
)
def test_the_commands_refuse_in_one_line_unless_allowed(out: Path, benches, capsys, args) -> None:
    argv = [a.format(out=out) for a in args]
    assert main(argv) == 1
    err = capsys.readouterr().err
    why = f"tasks.jsonl sha256 {SHA['tasks']} and {_tasks_digest(benches['reworded'])}"
    assert err == (
        f"error: {_refusal(out, benches, 'sim-vlm-a', 'sim-vlm-b', why)} "
        "(--allow-different-benchmarks compares them anyway)\n"
    )
    assert main([*argv, "--allow-different-benchmarks"]) == 0
    assert capsys.readouterr().out
