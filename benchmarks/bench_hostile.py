"""Hostile input to the replay, at full size (not a test): the figures of docs/REPLAY.md,
"Hostile input", and of docs/LIVE.md, "A hostile model server" (the `live_` cases).

    python benchmarks/bench_hostile.py [--work DIR] [--keep] [--only NAME,...]

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
    episode_mcap_path,
    manifest_path,
    mcap_dir,
    quarantine_path,
)
from tests.bounded import Finished, run_bounded  # noqa: E402
from tests.hostile import picture_inputs as pictures  # noqa: E402
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
    while not processes.children(proc.pid) and proc.poll() is None:
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
        f"{len(kids)} process(es) below it (the worker, forked: no resource tracker); "
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


# ---------------------------------------------------------------- vge run, a hostile server
# `vge run` against tests/vge_analytics/live/chat_server.py on 127.0.0.1, every request
# answered alike; run through /usr/bin/time -v (its figures: the peak resident memory and
# the wall time), under an address-space bound of 4 GB. The kettle benchmark of the live
# tests, one episode. For the figures of the code before the bounds, run this file with
# PYTHONPATH pointing at that code (the server and the table stay this checkout's).

LIVE_BOUND = 4 << 30


def _timed_vge(*args: object, timeout: float) -> tuple[Finished, float, int]:
    """`vge ARGS` under /usr/bin/time -v: the process, its wall seconds, its peak RSS."""
    done = run_bounded(
        ["/usr/bin/time", "-v", *VGE, *map(str, args)], address_space=LIVE_BOUND, timeout=timeout
    )
    figures = dict(
        line.strip().rsplit(": ", 1) for line in done.stderr.splitlines() if line.startswith("\t")
    )
    if "Maximum resident set size (kbytes)" not in figures:  # killed at the timeout
        return done, done.seconds, done.peak_memory
    h, m, sec = ("0:" + figures["Elapsed (wall clock) time (h:mm:ss or m:ss)"]).split(":")[-3:]
    seconds = int(h) * 3600 + int(m) * 60 + float(sec)
    return done, seconds, int(figures["Maximum resident set size (kbytes)"]) * 1024


def _live(work: Path, case: str, reply: object, *options: str, timeout: float = 600.0) -> str:
    from tests.vge_analytics.live.chat_server import chat_server
    from tests.vge_analytics.live.conftest import write_kettle_bench

    bench = write_kettle_bench(work / "bench")
    run = work / "run"
    with chat_server([], then=reply) as server:  # type: ignore[arg-type]
        done, seconds, peak = _timed_vge(
            "run", bench, "--agent", "openai:scripted-vlm", "--out", run, "--base-url",
            server.url, "--limit", "1", "--retries", "1", "--retry-wait", "0.01",
            "--no-progress", *options, timeout=timeout,
        )  # fmt: skip
        requests = len(server.requests)
    notes = [f"requests: {requests}"]
    killed = seconds >= timeout
    if killed:
        notes.append(f"killed after {timeout:.0f} s, still reading")
    elif done.returncode not in (0, 2):
        notes.append(done.stderr.strip().splitlines()[0][:120] if done.stderr.strip() else "-")
    episodes = run / "episodes.jsonl"
    if episodes.exists():
        notes.append(f"episodes.jsonl {episodes.stat().st_size:,} bytes")
    if (run / "failures.jsonl").exists():
        reason = json.loads((run / "failures.jsonl").read_text().splitlines()[0])["reason"]
        notes.append(f"failure: {reason.split('; last: ')[-1]}")
    if (run / "run.json").exists():
        meta = json.loads((run / "run.json").read_text())["meta"]
        if "prompt_tokens" in meta:
            notes.append(f"run.json prompt_tokens {meta['prompt_tokens']:,}")
        if episodes.exists() and not killed:
            out = work / "out"
            replayed = vge("replay", run, "--bench", bench, "--out", out)
            said = replayed.stderr.strip()[:100]
            notes.append(f"replay: {quarantined(out) if replayed.returncode in (0, 2) else said}")
    shown = "-" if killed else f"{peak / MiB:,.0f}"
    return (
        f"| {case} | `vge run --limit 1 --retries 1` | {done.returncode} | {seconds:.1f} | "
        f"{shown} | {'; '.join(notes)} |"
    )


def live_huge_answer(work: Path) -> list[str]:
    from tests.vge_analytics.live.chat_server import huge

    return [_live(work, "every answer 1 GiB (Content-Length declared)", huge(1 << 30))]


def live_50mb_answer(work: Path) -> list[str]:
    from tests.vge_analytics.live.chat_server import huge

    return [_live(work, "every answer 50 MiB", huge(50 * MiB))]


def live_trickle(work: Path) -> list[str]:
    from tests.vge_analytics.live.chat_server import trickle

    reply = trickle(2.0, size=1000)
    case = "the answer's body trickled, a byte every 2 s (`--timeout 10`)"
    return [_live(work, case, reply, "--timeout", "10", timeout=180)]


def live_token_counts(work: Path) -> list[str]:
    from tests.vge_analytics.live.chat_server import Scripted, answer

    rows = []
    opens = "Thinking: the lid.\nAction: Push(coord=[480, 90], params=[1])"
    for case, tokens in (("negative token counts (-10^22)", -(10**22)), ("10^22 tokens", 10**22)):
        body = json.loads(answer(opens).body)
        body["usage"] = {"prompt_tokens": tokens, "completion_tokens": tokens}
        rows.append(_live(work / str(len(rows)), case, Scripted(200, json.dumps(body).encode())))
PILLOW_DECODE = """
import sys
from PIL import Image
with Image.open(sys.argv[1]) as img:
    rgb = img.convert("RGB")
print(*rgb.size)
"""
"""What every reader of a view picture did before: Pillow's own bomb check, then decoding."""


def _picture_note(command: str, root: Path, done: Finished) -> str:
    """What a reader of the picture benchmark made of its picture."""
    text = done.stdout_head.decode(errors="replace").strip()
    if command.startswith("vge replay"):
        from mcap.reader import make_reader

        with open(episode_mcap_path(root / "out", "r", "e1").local, "rb") as fh:
            messages = make_reader(fh).iter_messages(topics=["/camera"])
            return f"{sum(1 for _ in messages)} picture frame(s) in the MCAP file"
    if command.startswith("vge export"):
        return f"{len(list((root / 'atif' / 'r' / 'images').glob('*.jpg')))} picture(s) exported"
    return " ".join(text.splitlines()[-1:]).replace(f"{root}/bench/", "BENCH/")[:140]


def bomb_png(work: Path) -> list[str]:
    """A PNG of 13,370 x 13,370 pixels (half a megabyte, just under Pillow's bomb threshold)
    as a view's picture, beside the same benchmark with a picture of 640 x 480, each reader
    run on both in turn (a ratio holds on a busy machine where seconds do not); and, as the
    baseline of before, Pillow decoding it."""
    huge = pictures.huge_png(work / "huge.png", pictures.BOMB_SIDE)
    side = f"{pictures.BOMB_SIDE:,} x {pictures.BOMB_SIDE:,} ({huge.stat().st_size / MiB:.1f} MB)"
    sides = {
        "640 x 480": pictures.picture_bench(work / "small", None),
        side: pictures.picture_bench(work / "huge", huge.read_bytes()),
    }
    python = [sys.executable, "-c"]
    commands: list[tuple[str, Callable[[Path], list[object]]]] = [
        ("vge validate BENCH", lambda r: [*VGE, "validate", r / "bench"]),
        (
            "vge replay RUN --mcap",
            lambda r: [
                *VGE,
                "replay",
                r / "run",
                "--bench",
                r / "bench",
                "--out",
                r / "out",
                "--mcap",
            ],
        ),
        (
            "vge export OUT --format atif",
            lambda r: [*VGE, "export", r / "out", "--format", "atif", "--out", r / "atif"],
        ),
        ("dash.step_picture, view_picture", lambda r: [*python, pictures.VIEWER_SCRIPT, r / "out"]),
        ("DeviceEnv(BENCH).reset", lambda r: [*python, pictures.ENV_SCRIPT, r / "bench"]),
        (
            "Pillow: Image.open, convert",
            lambda r: [*python, PILLOW_DECODE, r / "bench" / pictures.FRONT],
        ),
    ]
    rows = []
    for command, args in commands:
        for picture, root in sides.items():
            cmd = [str(a) for a in args(root)]
            done = run_bounded(cmd, address_space=8 << 30, timeout=300.0)
            note = _picture_note(command, root, done)
            rows.append(row(f"a view picture of {picture}", command, done, note))
REPEAT = "sum(length(repeat(episode_id, 20000000)))"
"""A metric's numerator whose every value is 400 MB that DuckDB's memory limit does not count
(issue 25: it took `vge metrics` on the sample to 22.5 GB)."""


def metric_file_bound(work: Path) -> list[str]:
    """The `repeat` metric file in every command that evaluates one, on the bundled sample,
    with the default options (the memory limit sized from OUT: 513 MB); before each, the same
    command without it (the baseline)."""
    from tests.vge_analytics.metrics.metric_files import metric_text

    out, folder = work / "out", work / "metrics"
    folder.mkdir(parents=True)
    (folder / "repeat.sql").write_text(metric_text("Repeat", REPEAT, "count(*)"))
    runs = sorted((ROOT / "logs" / "runs").iterdir())
    vge("replay", *runs, "--bench", ROOT / "logs" / "bench", "--out", out)
    pair = ["sim-vlm-a", "sim-vlm-b"]
    cases = [  # (baseline or None, with the file)
        (["metrics"], ["metrics"]),
        (["compare", *pair], ["compare", *pair]),
        (["compare", "--all"], ["compare", "--all", "--metric", "Repeat"]),
        (None, ["rescore"]),  # rescore needs a folder
        (["sweep", "--lambdas", "2,3"], ["sweep", "--lambdas", "2,3", "--metrics", "Repeat"]),
    ]
    rows = []
    for baseline, hostile in cases:
        for args, extra in ((baseline, []), (hostile, ["--metrics-dir", folder])):
            if args is None:
                continue
            done = vge(args[0], out, *args[1:], *extra, timeout=300)
            said = done.stderr.strip().splitlines()[-1] if done.returncode else "computed"
            said = said.split("metric file ")[-1]
            case = "the `repeat` metric file" if extra else "no metric file (baseline)"
            shown = " ".join(["vge", args[0], "OUT", *args[1:]])
            rows.append(row(case, shown, done, said))
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
    live_huge_answer,
    live_50mb_answer,
    live_trickle,
    live_token_counts,
    bomb_png,
    metric_file_bound,
    *NEW_CASES,
]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--work", type=Path, help="where to generate the inputs (default: a temp dir)"
    )
    parser.add_argument("--keep", action="store_true", help="keep the generated inputs")
    parser.add_argument(
        "--only", help="the cases to run, comma-separated; `new`: those of decoding, paths and output"
    )
    args = parser.parse_args()
    only = None if args.only is None else set(args.only.split(","))
    if only is not None and "new" in only:
        only |= {case.__name__ for case in NEW_CASES}
    work = args.work or Path(tempfile.mkdtemp(prefix="vge-hostile-"))
    print(f"{os.cpu_count()} cores; Python {sys.version.split()[0]}; gzip level 1 inputs\n")
    print("| input | command | exit | seconds | peak MB | outcome |")
    print("|---|---|---|---|---|---|")
    try:
        for case in CASES:
            if only is not None and case.__name__ not in only:
                continue
            for line in case(work / case.__name__):
                print(line, flush=True)
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
