"""Hostile input to the replay, at full size (not a test): the figures of docs/REPLAY.md,
"Hostile input".

    python benchmarks/bench_hostile.py [--work DIR] [--keep]

Each case is generated under DIR (a temporary directory by default, removed unless --keep)
by `tests/hostile/replay_inputs.py`, the generators of the test module
(`tests/hostile/test_replay_input.py`, which runs the same cases smaller), and run as a real
`vge` process under an address-space bound of 8 GB (`tests.bounded`): exit code, wall
seconds, peak resident memory (of the largest process: `wait4`). Prints a Markdown table.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from replay.io import (  # noqa: E402
    EPISODES,
    EPISODES_GZ,
    manifest_path,
    mcap_dir,
    quarantine_path,
)
from tests.bounded import Finished, run_bounded  # noqa: E402
from tests.hostile import processes  # noqa: E402
from tests.hostile import replay_inputs as gen  # noqa: E402

VGE = [sys.executable, "-m", "vge_analytics.cli"]
MiB = 1 << 20
RECORDS = 10_000


def vge(*args: object, timeout: float = 600.0) -> Finished:
    return run_bounded([*VGE, *map(str, args)], address_space=8 << 30, timeout=timeout)


def row(case: str, command: str, done: Finished, note: str = "") -> str:
    return (
        f"| {case} | `{command}` | {done.returncode} | {done.seconds:.1f} | "
        f"{done.peak_memory / MiB:,.0f} | {note} |"
    )


def quarantined(out: Path) -> str:
    lines = quarantine_path(out).read_text().splitlines()
    kinds = [f"{r['kind']} (line {r['line']})" for r in map(json.loads, lines)]
    manifest = json.loads(manifest_path(out).read_text())
    return f"{manifest['totals']['replayed']:,} replayed; quarantined: {', '.join(kinds) or '-'}"


def _press_bench(work: Path, ids: list[str]) -> Path:
    """A benchmark of the two-state device `press`, a task for each id."""
    tasks = [gen.task(i, "press", "S1") for i in ids]
    return gen.write_bench(work / "bench", {"press": gen.line_ssm(2)}, tasks)


def _large_run(work: Path) -> tuple[Path, Path]:
    """The benchmark and a run of RECORDS records of 100 KB."""
    ids = [f"e{i}" for i in range(RECORDS)]
    run = gen.write_run(work / "run", (gen.padded(i, 100_000) for i in ids), gz=True)
    return _press_bench(work, ids), run


def large_records(work: Path) -> list[str]:
    bench, run = _large_run(work)
    size = (run / EPISODES_GZ).stat().st_size
    rows = []
    for workers in (1, 2):
        out = work / f"out-{workers}"
        done = vge("replay", run, "--bench", bench, "--out", out, "--workers", workers)
        rows.append(
            row(
                f"{RECORDS:,} records of 100 KB ({size / MiB:.1f} MB .gz)",
                f"vge replay RUN --workers {workers}",
                done,
                quarantined(out),
            )
        )
    return rows


def _endless(work: Path, chunk: bytes, times: int, what: str) -> list[str]:
    """One good record, then `times` MiB of `chunk` (compressed once, as gzip members)."""
    bench = _press_bench(work, ["e0"])
    run = gen.write_run(work / "run", [gen.episode("e0")], gz=True)
    gen.append_gzip(run / EPISODES_GZ, chunk * (MiB // len(chunk)), times)
    size = (run / EPISODES_GZ).stat().st_size
    out = work / "out"
    done = vge("replay", run, "--bench", bench, "--out", out)
    return [row(f"{what} ({size / MiB:.1f} MB .gz)", "vge replay RUN", done, quarantined(out))]


def long_line(work: Path) -> list[str]:
    return _endless(work, b"0", 512, "a line of 512 MiB, no newline")


def blank_run(work: Path) -> list[str]:
    return _endless(work, b"\n", 1024, "1 GiB of blank lines")


def device(work: Path) -> list[str]:
    bench = _press_bench(work, ["e0"])
    run = gen.write_run(work / "run", [])
    (run / EPISODES).unlink()
    (run / EPISODES).symlink_to("/dev/zero")
    done = vge("replay", run, "--bench", bench, "--out", work / "out")
    return [row("episodes.jsonl links to /dev/zero", "vge replay RUN", done, done.stderr.strip())]


def deep_step(work: Path) -> list[str]:
    bench = _press_bench(work, ["e0", "e1", "e2"])
    deep = gen.deep_step("e1", 1000)
    run = gen.write_run(work / "run", [gen.episode("e0"), deep, gen.episode("e2")])
    out = work / "out"
    done = vge("replay", run, "--bench", bench, "--out", out)
    return [row("a step nested 1,000 levels deep", "vge replay RUN", done, quarantined(out))]


def machines(work: Path) -> list[str]:
    rows = []
    cases: list[tuple[str, dict, str, int]] = [
        ("an SSM of 4,000 immediate transitions in a row", gen.chain_ssm(4000), "C4000", 1),
        ("a linear SSM of 1,000 states (a plan of 999 steps)", gen.line_ssm(1000), "S999", 999),
        (
            "a linear SSM of 100,000 states (a plan of 99,999 steps)",
            gen.line_ssm(100_000),
            "S99999",
            0,
        ),
    ]
    for i, (case, ssm, goal, steps) in enumerate(cases):
        bench = gen.write_bench(work / f"bench{i}", {"dev": ssm}, [gen.task("t", "dev", goal)])
        run = gen.write_run(work / f"run{i}", [gen.episode("t", steps=steps)] if steps else [])
        done = vge("validate", bench, *([run] if steps else []))
        command = "vge validate BENCH RUN" if steps else "vge validate BENCH"
        rows.append(row(case, command, done, done.stdout_head.decode().strip()))
        if steps:
            out = work / f"out{i}"
            done = vge("replay", run, "--bench", bench, "--out", out)
            rows.append(row(case, "vge replay RUN", done, quarantined(out)))
    return rows


def long_id(work: Path) -> list[str]:
    ids = ["é" * 290 + "/a", "x" * 300]
    bench = _press_bench(work, ids)
    run = gen.write_run(work / "run", [gen.episode(i) for i in ids])
    out = work / "out"
    done = vge("replay", run, "--bench", bench, "--out", out, "--mcap")
    longest = max(len(p.name.encode()) for p in mcap_dir(out, "run").iterdir())
    note = f"{quarantined(out)}; longest MCAP file name {longest} bytes"
    return [row("episode ids of 300 characters", "vge replay RUN --mcap", done, note)]


def long_run_id(work: Path) -> list[str]:
    bench = _press_bench(work, ["e0"])
    run = gen.write_run(work / "run", [gen.episode("e0")], run_id="r" * 300)
    done = vge("replay", run, "--bench", bench, "--out", work / "out")
    return [row("a run_id of 300 characters", "vge replay RUN", done, done.stderr.strip()[-90:])]


def killed_parent(work: Path) -> list[str]:
    bench, run = _large_run(work)
    cmd = [*VGE, "replay", str(run), "--bench", str(bench), "--out", str(work / "out")]
    proc = subprocess.Popen([*cmd, "--workers", "2"], stderr=subprocess.DEVNULL)
    while len(processes.children(proc.pid)) < 2 and proc.poll() is None:
        time.sleep(0.05)
    time.sleep(3)  # in the middle of the replay
    kids = processes.children(proc.pid)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    killed = time.monotonic()
    left = processes.left_after(kids, 60)
    gone = time.monotonic() - killed
    return [
        f"| `kill -9` of `vge replay RUN --workers 2`, 3 s in | - | - | - | - | "
        f"{len(kids)} processes below it (the worker, the resource tracker); "
        f"{len(left)} left after {gone:.2f} s |"
    ]


def label_response(work: Path) -> list[str]:
    from replay import parse_action
    from replay.kernel import parse_fields

    text = "-" * 7_000_000 + "action:" * 1_000_000
    rows = []
    for name, parse in (("reference", parse_action), ("kernel", parse_fields)):
        started = time.perf_counter()
        parse(text)
        seconds = time.perf_counter() - started
        rows.append(
            f"| a response of 14 MB: 7 MB of `-`, a million `action:` labels | {name} parser | "
            f"- | {seconds:.2f} | - | |"
        )
    return rows


def _said(text: str | bytes, work: Path) -> str:
    """A message, its paths relative to the case's folder."""
    text = text.decode() if isinstance(text, bytes) else text
    return " ".join(text.replace(f"{work}/", "").split())


def _one_bad_among_good(work: Path) -> tuple[Path, Path]:
    """Benchmark and run of e0, e1, e2 on `press` (a case then spoils one of them)."""
    bench = _press_bench(work, ["e0", "e1", "e2"])
    run = gen.write_run(work / "run", [gen.episode(f"e{i}") for i in range(3)])
    return bench, run


def not_utf8(work: Path) -> list[str]:
    bench, run = _one_bad_among_good(work)
    bad = gen.episode("e1").replace(b"Thinking", b"Think\xffing")
    (run / EPISODES).write_bytes(b"\n".join([gen.episode("e0"), bad, gen.episode("e2")]) + b"\n")
    out = work / "out"
    done = vge("replay", run, "--bench", bench, "--out", out)
    rows = [row("an episode line with a byte that is not UTF-8", "vge replay RUN", done, quarantined(out))]
    lines = (bench / "tasks.jsonl").read_bytes().splitlines()
    lines[1] = lines[1].replace(b'"e1"', b'"e1\xff"')
    (bench / "tasks.jsonl").write_bytes(b"\n".join(lines) + b"\n")
    done = vge("validate", bench)
    note = _said(done.stdout_head.decode().splitlines()[0], work)
    rows.append(row("a line of tasks.jsonl with a byte that is not UTF-8", "vge validate BENCH", done, note))
    return rows


def huge_box(work: Path) -> list[str]:
    bench, run = _one_bad_among_good(work)
    ssm = json.loads(json.dumps(gen.line_ssm(2)))  # its boxes are one shared dict
    ssm["states"]["S0"]["on"]["button"][0]["bbox"][0]["coordinate"] = [0, 0, 1e308, 1e308, 1e308, 1e308]
    (bench / "ssm" / "big.json").write_text(json.dumps(ssm))
    with open(bench / "tasks.jsonl", "a") as fh:
        fh.write(json.dumps(gen.task("e3", "big", "S1")) + "\n")
    with open(run / EPISODES, "ab") as fh:
        fh.write(gen.episode("e3") + b"\n")
    done = vge("validate", bench)
    note = _said(done.stdout_head.decode().splitlines()[0], work).split(": ", 1)[-1]
    rows = [row("a box of 1e308 in an SSM", "vge validate BENCH", done, note)]
    out = work / "out"
    done = vge("replay", run, "--bench", bench, "--out", out)
    rows.append(row("a box of 1e308 in an SSM", "vge replay RUN", done, quarantined(out)))
    return rows


def wide_meta(work: Path) -> list[str]:
    bench, run = _one_bad_among_good(work)
    out = work / "out"
    first = vge("replay", run, "--bench", bench, "--out", out)
    assert first.returncode == 0, first.stderr
    rows = []
    cases = [
        ('meta {"x": 2**64}, rerun into an OUT', {"x": 1 << 64}),
        ("meta of 20,000 keys", {f"key{i:06}": i for i in range(20_000)}),
        ("meta of 2,500,000 keys", {f"key{i:07}": i for i in range(2_500_000)}),
    ]
    for case, meta in cases:
        header = {"run_id": "run", "model": "m", "agent_kind": "scripted", "meta": meta}
        (run / "run.json").write_text(json.dumps(header))
        size = (run / "run.json").stat().st_size
        done = vge("replay", run, "--bench", bench, "--out", out)
        note = f"run.json of {size / MiB:.2f} MB; " + _said(done.stderr, work)
        rows.append(row(case, "vge replay RUN", done, note))
    return rows


def device_paths(work: Path) -> list[str]:
    tasks = [gen.task("e0", "press", "S1"), gen.task("e1", "../../x", "S1"), gen.task("e2", "d\0x", "S1")]
    bench = gen.write_bench(work / "bench", {"press": gen.line_ssm(2)}, tasks)
    with open(work / "x.json", "wb") as fh:  # where ../../x leads: 60 GB, sparse
        fh.truncate(60 << 30)
    run = gen.write_run(work / "run", [gen.episode(f"e{i}") for i in range(3)])
    out = work / "out"
    done = vge("replay", run, "--bench", bench, "--out", out)
    case = "task device_ids `../../x` (a sparse file of 60 GB there) and `d\\0x`"
    return [row(case, "vge replay RUN", done, quarantined(out))]


def disk_full(work: Path) -> list[str]:
    """The manifest cannot be written (a file-size limit of 30 KB stands for a full disk)."""
    devices = {f"d{i}": gen.line_ssm(2) for i in range(300)}
    bench = gen.write_bench(work / "bench", devices, [gen.task(f"e{i}", f"d{i}", "S1") for i in range(300)])
    small = gen.write_run(work / "a", [gen.episode("e0")], run_id="a")
    wide = gen.write_run(work / "b", [gen.episode(f"e{i}") for i in range(300)], run_id="b")
    out = work / "out"
    assert vge("replay", small, "--bench", bench, "--out", out).returncode == 0
    before = {p: p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()}
    limited = ["bash", "-c", "trap '' XFSZ; ulimit -f 30; exec \"$@\"", "-", *VGE]
    args = ["replay", small, wide, "--bench", bench, "--out", out]
    done = run_bounded([*limited, *map(str, args)], address_space=8 << 30, timeout=600)
    same = {p: p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()} == before
    note = f"OUT {'unchanged' if same else 'CHANGED'}; {_said(done.stderr, work)}"
    return [row("300-device run, disk full at manifest.json", "vge replay A B", done, note)]


NEW_CASES = [not_utf8, huge_box, wide_meta, device_paths, disk_full]
"""The cases of issue 25's decoding, paths and output (`--only new`)."""

CASES: list[Callable[[Path], list[str]]] = [
    large_records,
    long_line,
    blank_run,
    device,
    deep_step,
    machines,
    long_id,
    long_run_id,
    killed_parent,
    label_response,
    *NEW_CASES,
]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--work", type=Path, help="where to generate the inputs (default: a temp dir)"
    )
    parser.add_argument("--keep", action="store_true", help="keep the generated inputs")
    parser.add_argument(
        "--only", choices=["new"], help="only the cases of decoding, paths and output"
    )
    args = parser.parse_args()
    work = args.work or Path(tempfile.mkdtemp(prefix="vge-hostile-"))
    print(f"{os.cpu_count()} cores; Python {sys.version.split()[0]}; gzip level 1 inputs\n")
    print("| input | command | exit | seconds | peak MB | outcome |")
    print("|---|---|---|---|---|---|")
    try:
        for case in NEW_CASES if args.only else CASES:
            for line in case(work / case.__name__):
                print(line, flush=True)
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
