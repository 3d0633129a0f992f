"""Bytes that are not UTF-8, numbers the planner or the tables cannot take, and a run.json
meta too wide (PROTOCOL §1.5): the record they are in is quarantined or refused in one line
naming its file (and line), in every reader, and the good records beside it are replayed."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from .outcomes import counts, one_line_error, quarantine
from .replay_inputs import episode, line_ssm, task, write_bench, write_run

BAD = b"\xff"


def three_episodes(tmp_path: Path, *, middle: bytes | None = None) -> Path:
    """A run of e0, (middle or e1), e2, each a press that reaches the goal."""
    return write_run(tmp_path / "run", [episode("e0"), middle or episode("e1"), episode("e2")])


def press_bench(tmp_path: Path) -> Path:
    """Device `press` (one press to S1) and tasks e0..e2 on it."""
    tasks = [task(f"e{i}", "press", "S1") for i in range(3)]
    return write_bench(tmp_path / "bench", {"press": line_ssm(2)}, tasks)


def add_device(bench: Path, device: str, ssm: bytes) -> None:
    """BENCH/ssm/<device>.json holding `ssm`, and task e3 on it."""
    (bench / "ssm" / f"{device}.json").write_bytes(ssm)
    with open(bench / "tasks.jsonl", "a") as fh:
        fh.write(json.dumps(task("e3", device, "S1")) + "\n")


def replays_all_but(vge_here, run: Path, bench: Path, out: Path, bad: tuple[int, str]) -> None:
    """`vge replay` exits 2 having quarantined the one bad record and replayed the others."""
    done = vge_here("replay", run, "--bench", bench, "--out", out)
    assert done.returncode == 2, done.stderr
    assert quarantine(out) == [bad]
    manifest = counts(out)
    assert manifest.replayed == manifest.lines_read - 1


def errors(stdout: str) -> list[str]:
    return [line for line in stdout.splitlines() if line.startswith("error")]


def test_an_episode_line_not_utf8_is_quarantined(tmp_path, vge_here) -> None:
    bad = episode("e1").replace(b"Thinking", b"Think" + BAD + b"ing")
    run = three_episodes(tmp_path, middle=bad)
    bench = press_bench(tmp_path)
    out = tmp_path / "out"
    replays_all_but(vge_here, run, bench, out, (2, "malformed_json"))
    at = bad.index(BAD)
    reason = json.loads((out / "quarantine.jsonl").read_text())["reason"]
    assert reason == f"not valid JSON: invalid UTF-8 (byte {at})"

    done = vge_here("validate", bench, run)
    assert errors(done.stdout) == [
        f"error   {run / 'episodes.jsonl'}:2: invalid UTF-8 (byte {at})"
    ]


def test_a_task_line_not_utf8_is_named_and_its_episode_quarantined(tmp_path, vge_here) -> None:
    bench = press_bench(tmp_path)
    line = json.dumps(task("e1", "press", "S1")).encode().replace(b'"e1"', b'"e1' + BAD + b'"')
    lines = (bench / "tasks.jsonl").read_bytes().splitlines()
    lines[1] = line
    (bench / "tasks.jsonl").write_bytes(b"\n".join(lines) + b"\n")
    run = three_episodes(tmp_path)
    done = vge_here("validate", bench)
    assert errors(done.stdout) == [
        f"error   {bench / 'tasks.jsonl'}:2: invalid UTF-8 (byte {line.index(BAD)})"
    ]
    replays_all_but(vge_here, run, bench, tmp_path / "out", (2, "unknown_episode"))


def test_an_ssm_not_utf8_quarantines_its_episodes(tmp_path, vge_here) -> None:
    text = json.dumps(line_ssm(2), indent=1).encode().replace(b'"Line"', b'"Li' + BAD + b'ne"')
    bench = press_bench(tmp_path)
    add_device(bench, "other", text)
    run = write_run(tmp_path / "run", [episode(f"e{i}") for i in range(4)])
    done = vge_here("validate", bench)
    ssm = bench / "ssm" / "other.json"
    assert errors(done.stdout) == [
        f"error   {ssm}:2: invalid UTF-8 (byte {text.index(BAD)})",
        f"error   {bench / 'tasks.jsonl'}:4 [episode 'e3']: device 'other' has an invalid SSM",
    ]
    replays_all_but(vge_here, run, bench, tmp_path / "out", (4, "invalid_ssm"))


def test_a_run_json_not_utf8_is_refused_in_one_line(tmp_path, vge_here) -> None:
    run = three_episodes(tmp_path)
    text = b'{"run_id": "r",\n "model": "m' + BAD + b'", "agent_kind": "vlm"}'
    (run / "run.json").write_bytes(text)
    done = vge_here("replay", run, "--bench", press_bench(tmp_path), "--out", tmp_path / "out")
    assert done.returncode == 1
    assert one_line_error(done.stderr) == (
        f"error: {run / 'run.json'}:2: invalid UTF-8 (byte {text.index(BAD)})"
    )


@pytest.mark.parametrize(
    "coordinate",
    [
        [0, 0, 1e308, 1e308, 1e308, 1e308],  # x 1000/W overflows: inf, then int(inf)
        [1e308, 0, 1e307, 10, 1.7e308, 100],  # inside its image, whose corner is inf - inf
        [0, 0, 5, 5, 1e308, 1e308],  # fits, but past any picture
        [0, 0, 20_000_000, 10, 20_000_000, 100],
    ],
    ids=["1e308", "nan", "huge-image", "2e7"],
)
def test_boxes_the_planner_cannot_take_are_refused_by_validation(
    coordinate, tmp_path, vge_here
) -> None:
    ssm = json.loads(json.dumps(line_ssm(2)))
    ssm["states"]["S0"]["on"]["button"][0]["bbox"][0]["coordinate"] = coordinate
    bench = press_bench(tmp_path)
    add_device(bench, "big", json.dumps(ssm).encode())
    run = write_run(tmp_path / "run", [episode(f"e{i}") for i in range(4)])
    done = vge_here("validate", bench, run)
    assert done.returncode == 1
    numbers = ", ".join(f"{v:g}" for v in map(float, coordinate))
    assert errors(done.stdout)[0] == (
        f"error   {bench / 'ssm' / 'big.json'} [state 'S0', component 'button', transition 0, "
        f"bbox 0]: coordinate [{numbers}] holds a number past 16,777,216 pixels"
    )
    replays_all_but(vge_here, run, bench, tmp_path / "out", (4, "invalid_ssm"))


def test_a_box_at_the_bound_replays(tmp_path, vge_here) -> None:
    ssm = json.loads(json.dumps(line_ssm(2)))
    side = 1 << 24
    ssm["states"]["S0"]["on"]["button"][0]["bbox"][0]["coordinate"] = [0, 0, side, side, side, side]
    bench = write_bench(tmp_path / "bench", {"press": ssm}, [task("e0", "press", "S1")])
    run = write_run(tmp_path / "run", [episode("e0")])
    done = vge_here("replay", run, "--bench", bench, "--out", tmp_path / "out")
    assert done.returncode == 0, done.stderr
    assert counts(tmp_path / "out").replayed == 1


def _header(meta: object) -> bytes:
    return json.dumps({"run_id": "r", "model": "m", "agent_kind": "vlm", "meta": meta}).encode()


@pytest.mark.parametrize(
    ("meta", "reason"),
    [
        (b'{"x": 18446744073709551616}', "meta.x is an integer of 65 bits; the tables hold 64 (signed)"),
        (b'{"a": {"b": [1, -9223372036854775809]}}', "meta.a.b[1] is an integer of 65 bits; the tables hold 64 (signed)"),
        (b'{"x": 1' + b"0" * 400 + b"}", "meta.x is an integer of 1329 bits; the tables hold 64 (signed)"),
        (json.dumps({f"k{i}": i for i in range(257)}).encode(), "meta has 257 keys; at most 256"),
        (json.dumps({"k": "x" * 70_000}).encode(), "meta takes 70,008 bytes as JSON; at most 65,536"),
    ],
    ids=["2^64", "nested -2^63-1", "10^400", "257 keys", "70 KB"],
)  # fmt: skip
def test_a_meta_the_tables_cannot_take_is_refused_before_anything_changes(
    meta, reason, tmp_path, vge_here
) -> None:
    """A rerun into an OUT already written: refused in one line, every byte of OUT kept (the
    partition used to be swapped in before the runs table failed, and every rerun failed)."""
    run = write_run(tmp_path / "run", [episode("e0")], run_id="r")
    bench = press_bench(tmp_path)
    out = tmp_path / "out"
    assert vge_here("replay", run, "--bench", bench, "--out", out).returncode == 0
    before = {p: p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()}
    (run / "run.json").write_bytes(_header(0).replace(b'"meta": 0', b'"meta": ' + meta))
    (run / "episodes.jsonl").write_bytes(episode("e1") + b"\n")
    done = vge_here("replay", run, "--bench", bench, "--out", out)
    assert done.returncode == 1
    assert one_line_error(done.stderr) == f"error: {run / 'run.json'}: {reason}"
    assert {p: p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()} == before
    done = vge_here("validate", bench, run)
    assert errors(done.stdout) == [f"error   {run / 'run.json'}: {reason}"]


def test_a_meta_at_the_bounds_replays(tmp_path, vge_here) -> None:
    meta = {f"k{i:03}": i for i in range(255)}
    meta["z"] = (1 << 63) - 1
    run = write_run(tmp_path / "run", [episode("e0")], run_id="r")
    (run / "run.json").write_bytes(_header(meta))
    out = tmp_path / "out"
    done = vge_here("replay", run, "--bench", press_bench(tmp_path), "--out", out)
    assert done.returncode == 0, done.stderr
    import pyarrow.parquet as pq

    runs = pq.read_table(out / "runs" / "runs.parquet")
    assert runs.column("meta_z").to_pylist() == [(1 << 63) - 1]
    assert len([n for n in runs.column_names if n.startswith("meta_")]) == 256


def test_a_run_json_past_a_mebibyte_is_refused_unread(tmp_path, vge_here) -> None:
    run = write_run(tmp_path / "run", [episode("e0")], run_id="r")
    (run / "run.json").write_bytes(_header({"k": "x" * (1 << 20)}))
    done = vge_here("validate", press_bench(tmp_path), run)
    assert errors(done.stdout) == [
        f"error   {run / 'run.json'}: larger than 1,048,576 bytes, the maximum size of a record"
    ]
