"""Hostile input to the replay (PROTOCOL §1.5): every input replays or is refused, in bounded
time and memory, with one clear line; the good records are replayed.

Inputs are generated (`replay_inputs`), at sizes smaller than docs/REPLAY.md's figures
("Hostile input", measured by benchmarks/bench_hostile.py) but through the same mechanisms
(a lower `--max-record-bytes`, smaller blocks). What could eat memory runs as a real `vge`
process under an address-space bound (`tests.bounded`), and its peak is judged against the
same command on three good records.
"""

from __future__ import annotations

import gzip
import hashlib
import json
import os
import random
import subprocess
import sys
import time
from pathlib import Path

import msgspec
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import replay
from replay.io import _lines
from tests.bounded import run_bounded

from .outcomes import counts, one_line_error, quarantine
from .processes import children, left_after
from .replay_inputs import (
    append_gzip,
    chain_ssm,
    deep_step,
    episode,
    line_ssm,
    nested,
    padded,
    task,
    write_bench,
    write_run,
    zeros,
)

VGE = [sys.executable, "-m", "vge_analytics.cli"]
MiB = 1 << 20
GOOD = 2000
"""Tasks e0 ... e1999 on the two-state device `press` (one press reaches the goal)."""


@pytest.fixture(scope="module")
def bench(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("bench")
    return write_bench(
        root, {"press": line_ssm(2)}, [task(f"e{i}", "press", "S1") for i in range(GOOD)]
    )


def vge_bounded(*args: str | Path, timeout: float = 60.0):
    """`vge` as a real process under an address-space bound (`tests.bounded`)."""
    return run_bounded([*VGE, *map(str, args)], timeout=timeout)


@pytest.fixture(scope="module")
def baseline(bench: Path, tmp_path_factory: pytest.TempPathFactory):
    """`vge replay` of three good records: the process's own size and start-up time."""
    root = tmp_path_factory.mktemp("baseline")
    run = write_run(root / "run", [episode(f"e{i}") for i in range(3)])
    done = vge_bounded("replay", run, "--bench", bench, "--out", root / "out")
    assert done.returncode == 0, done.stderr
    return done


# ------------------------------------------------------------------- limits in bytes


def test_records_of_100_kb_replay_in_bounded_memory(bench, baseline, tmp_path) -> None:
    # 2,000 records of 100 KB: 200 MB in one batch of lines, cut by bytes into 32 MiB ones.
    # Batches of lines only made this run peak at 1.3 GB (4,096 such lines: 3.2 GB).
    run = write_run(tmp_path / "run", (padded(f"e{i}", 100_000) for i in range(GOOD)), gz=True)
    done = vge_bounded("replay", run, "--bench", bench, "--out", tmp_path / "out", timeout=120)
    assert done.returncode == 0, done.stderr
    assert counts(tmp_path / "out").replayed == GOOD
    # 336 lines make a batch of 32 MiB or more: five of them, and 320 lines
    assert len(list((tmp_path / "out" / "steps" / "run_id=run").iterdir())) == 6
    assert done.peak_memory < baseline.peak_memory + 600 * MiB, done.peak_memory
    assert done.seconds < baseline.seconds + 60  # generous: the machine may be loaded


def test_batches_are_cut_by_bytes(tmp_path) -> None:
    lines = [padded(f"e{i}", 10_000) for i in range(100)]
    path = write_run(tmp_path, lines) / "episodes.jsonl"
    reader = replay.io._reading.LineReader(replay.location(path), 30, 45_000, MiB)
    sizes = [(len(b), sum(len(raw) for _, raw in b)) for b in reader.batches()]
    # Cut once a batch holds 45,000 bytes (the fifth line of 10,000), else at 30 lines.
    assert sizes == [(5, 50_000)] * 20
    reader = replay.io._reading.LineReader(replay.location(path), 30, 10 * MiB, MiB)
    assert [len(b) for b in reader.batches()] == [30, 30, 30, 10]


def test_a_line_too_long_is_quarantined_without_being_held(bench, baseline, tmp_path) -> None:
    """Three good records, one line of 64 MiB with no newline (a 64 KB .gz), one more good
    record: the long one is quarantined at its line after 1 MiB is read, the reading of the
    file stops there, and nothing near its size is ever in memory."""
    run = tmp_path / "run"
    write_run(run, [episode(f"e{i}") for i in range(3)], gz=True)
    append_gzip(run / "episodes.jsonl.gz", b"0" * MiB, 64)
    append_gzip(run / "episodes.jsonl.gz", b"\n" + episode("e3") + b"\n", 1)
    out = tmp_path / "out"
    done = vge_bounded("replay", run, "--bench", bench, "--out", out, "--max-record-bytes", MiB)
    assert done.returncode == 2, done.stderr
    assert quarantine(out) == [(4, "record_too_large")]
    c = counts(out)
    assert (c.lines_read, c.replayed, c.quarantined) == (4, 3, 1)
    reason = json.loads((out / "quarantine.jsonl").read_text())["reason"]
    assert reason.startswith("line longer than 1,048,576 bytes, the maximum size of a record")
    assert done.peak_memory < baseline.peak_memory + 32 * MiB, done.peak_memory
    assert done.seconds < baseline.seconds + 30


def test_the_bound_is_an_option_of_the_run(bench, tmp_path, vge_here) -> None:
    """A run replayed with another bound is replayed again (its records may be judged
    otherwise); the manifest names the bound unless it is the default; `vge validate` reads
    the runs within the same bound."""
    run = write_run(tmp_path / "run", [episode("e0"), padded("e1", 5000), episode("e2")])
    out = tmp_path / "out"
    first = replay.replay_runs([run], bench, out, progress=False)
    assert (first.replayed, first.exit_code) == (["run"], 0)
    assert "max_record_bytes" not in (out / "manifest.json").read_text()
    again = replay.replay_runs([run], bench, out, progress=False, max_record_bytes=4096)
    assert (again.replayed, again.exit_code) == (["run"], 2)
    assert quarantine(out) == [(2, "record_too_large")]
    assert replay.read_manifest(out).runs[0].options.max_record_bytes == 4096
    same = replay.replay_runs([run], bench, out, progress=False, max_record_bytes=4096)
    assert (same.skipped, same.exit_code) == (["run"], 2)

    assert vge_here("validate", bench, run).returncode == 0
    done = vge_here("validate", bench, run, "--max-record-bytes", 4096)
    assert done.returncode == 1
    assert f"error   {run / 'episodes.jsonl'}:2: line longer than 4,096 bytes" in done.stdout


@pytest.mark.parametrize(
    ("name", "content", "line"),
    [
        ("endless zeros", b"0", 3),  # one line that never ends
        ("endless newlines", b"\n", 3),  # blank lines without end: a run from line 3
        ("endless blank lines", b" \t\r\n", 3),
    ],
)
def test_an_endless_input_is_read_up_to_the_bound(
    bench, baseline, tmp_path, name, content, line
) -> None:
    run = tmp_path / "run"
    write_run(run, [episode("e0"), episode("e1")], gz=True)
    # 1 GiB inflated: the bound, not the end of the file, stops the reading
    append_gzip(run / "episodes.jsonl.gz", content * (MiB // len(content)), 1024)
    out = tmp_path / "out"
    done = vge_bounded("replay", run, "--bench", bench, "--out", out, "--max-record-bytes", MiB)
    assert done.returncode == 2, done.stderr
    assert quarantine(out) == [(line, "record_too_large")]
    assert counts(out).replayed == 2
    assert done.peak_memory < baseline.peak_memory + 32 * MiB, done.peak_memory
    assert done.seconds < baseline.seconds + 30, name  # 1 GiB would take minutes


def test_a_device_or_a_pipe_is_refused_in_one_line(bench, tmp_path) -> None:
    run = write_run(tmp_path / "run", [])
    (run / "episodes.jsonl").unlink()
    (run / "episodes.jsonl").symlink_to("/dev/zero")
    done = vge_bounded("replay", run, "--bench", bench, "--out", tmp_path / "out")
    assert done.returncode == 1
    assert one_line_error(done.stderr) == (
        f"error: {run / 'episodes.jsonl'}: not a regular file "
        "(a device, a pipe or a directory is no input)"
    )
    (run / "episodes.jsonl").unlink()
    os.mkfifo(run / "episodes.jsonl")  # opening it would wait for a writer for ever
    done = vge_bounded("replay", run, "--bench", bench, "--out", tmp_path / "out")
    assert done.returncode == 1 and "episodes.jsonl: not a regular file" in done.stderr
    (run / "run.json").unlink()
    (run / "run.json").symlink_to("/dev/zero")
    done = vge_bounded("replay", run, "--bench", bench, "--out", tmp_path / "out")
    assert done.returncode == 1
    assert one_line_error(done.stderr).endswith(
        "run.json: not a regular file (a device, a pipe or a directory is no input)"
    )


def test_line_splitting_is_linear(tmp_path, monkeypatch: pytest.MonkeyPatch) -> None:
    # A 32 MiB line read in blocks of 4 KiB: 8,192 blocks. Joining the line again at every
    # block (as the reader did) copies 137 GB; joined once, 32 MiB.
    monkeypatch.setattr(_lines, "_BLOCK", 4096)
    path = tmp_path / "episodes.jsonl.gz"
    with gzip.open(path, "wb", compresslevel=1) as fh:
        fh.write(b"{}\n")
        for block in zeros(32 * MiB):
            fh.write(block)
        fh.write(b"\n{}")
    started = time.monotonic()
    got = [(n, len(raw)) for n, raw in replay.io.iter_lines(path)]
    assert got == [(1, 2), (2, 32 * MiB), (3, 2)]
    assert time.monotonic() - started < 15  # 0.3 s here; minutes if quadratic


@settings(max_examples=300, deadline=None)
@given(
    data=st.lists(st.sampled_from([b"\n", b" ", b"\t", b"a", b"bc", b"\r\n"]), max_size=40).map(
        b"".join
    ),
    limit=st.integers(1, 12),
    block=st.integers(1, 8),
)
def test_block_boundaries_never_change_the_lines(data: bytes, limit: int, block: int) -> None:
    """The reader's verdicts depend on the bytes only: read whole or in blocks of any size,
    the same lines come out, and the same line too large or run of blank lines."""

    def read(size: int) -> list[tuple[int, object]]:
        lines = _lines._Lines("f", limit)
        out: list[tuple[int, object]] = []
        try:
            for start in range(0, len(data), size):
                out.extend(lines.split(data[start : start + size]))
            out.extend(lines.end())
        except replay.RecordTooLarge as exc:
            out.append((exc.line or 0, exc.message.split(",")[0]))
        return out

    assert read(block) == read(len(data) + 1)


# ------------------------------------------------------------------------------ depth


def test_a_deep_step_is_quarantined_and_the_rest_replayed(bench, tmp_path, vge_here) -> None:
    deep = deep_step("e1", 1000)
    run = write_run(tmp_path / "run", [episode("e0"), deep, episode("e2"), episode("e3")])
    out = tmp_path / "out"
    done = vge_here("replay", run, "--bench", bench, "--out", out)
    assert done.returncode == 2, done.stderr
    assert quarantine(out) == [(2, "malformed_json")]
    reason = json.loads((out / "quarantine.jsonl").read_text())["reason"]
    at = deep.index(b"[[") + 253  # the record's object, steps and step are 3 levels
    assert reason == f"not valid JSON: JSON is nested deeper than 256 levels (byte {at})"
    assert counts(out).replayed == 3


def test_the_depth_bound_is_the_same_in_every_process(
    bench, tmp_path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """256 levels decode and 257 do not, in this process and in a worker process alike (the
    decoder alone gives up where each one's stack does, deeper in a worker)."""
    monkeypatch.setattr(replay.io._job, "BATCH_LINES", 4)  # batch 1 goes to the worker
    good = [episode(f"e{i}") for i in range(4)]
    deep = [deep_step(f"e{4 + i}", depth) for i, depth in enumerate([252, 253, 254, 600])]
    run = write_run(tmp_path / "run", good + deep)
    tables = []
    for workers in (1, 2):
        out = tmp_path / f"out{workers}"
        replay.replay_runs([run], bench, out, workers=workers, progress=False)
        assert quarantine(out) == [(7, "malformed_json"), (8, "malformed_json")]
        tables.append(pq.read_table(out / "episodes" / "run_id=run" / "part-00001.parquet"))
    assert tables[0].column("episode_id").to_pylist() == ["e4", "e5"]
    assert tables[0].equals(tables[1])


def test_deep_headers_tasks_and_machines_name_their_file(bench, tmp_path, vge_here) -> None:
    header = {"run_id": "r", "model": "m", "agent_kind": "vlm", "meta": {"x": 0}}
    text = json.dumps(header, indent=1).replace('"x": 0', '"x": ' + nested(300))
    run = write_run(tmp_path / "run", [episode("e0")])
    (run / "run.json").write_text(text)
    done = vge_here("replay", run, "--bench", bench, "--out", tmp_path / "out")
    assert done.returncode == 1
    at = text.index("[[") + 254  # meta is the second level
    assert one_line_error(done.stderr) == (
        f"error: {run / 'run.json'}:6: JSON is nested deeper than 256 levels (byte {at})"
    )

    tasks = [json.dumps(task("t0", "press", "S1")), json.dumps(task("t1", "press", "S1"))]
    tasks[1] = tasks[1][:-1] + ', "x": ' + nested(400) + "}"
    ssm = json.dumps(line_ssm(2), indent=1).replace('"name": "Line"', '"x": ' + nested(300))
    root = write_bench(tmp_path / "bench", {"press": line_ssm(2)}, [])
    (root / "tasks.jsonl").write_text("\n".join(tasks) + "\n")
    (root / "ssm" / "deep.json").write_text(ssm)
    done = vge_here("validate", root)
    assert done.returncode == 1
    shown = done.stdout.splitlines()
    assert [line for line in shown if line.startswith("error")] == [
        f"error   {root / 'ssm' / 'deep.json'}:2: JSON is nested deeper than 256 levels "
        f"(byte {ssm.index('[[') + 255})",
        f"error   {root / 'tasks.jsonl'}:2: JSON is nested deeper than 256 levels "
        f"(byte {tasks[1].index('[[') + 255})",
    ]


# ---------------------------------------------------------------- long and wide machines


@pytest.mark.parametrize(
    ("ssm", "goal", "steps"),
    [(line_ssm(1000), "S999", 999), (chain_ssm(4000), "C4000", 1)],
    ids=["1000-state line", "4000-state immediate chain"],
)
def test_long_machines_validate_and_replay(ssm, goal, steps, tmp_path, vge_here) -> None:
    root = write_bench(tmp_path / "bench", {"dev": ssm}, [task("t", "dev", goal)])
    run = write_run(tmp_path / "run", [episode("t", steps=steps)])
    done = vge_here("validate", root, run)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("OK 1 SSM(s), 1 task(s), 1 run(s)")
    done = vge_here("replay", run, "--bench", root, "--out", tmp_path / "out")
    assert done.returncode == 0, done.stderr
    episodes = pq.read_table(tmp_path / "out" / "episodes", partitioning=None).to_pylist()
    assert [(e["success"], e["L_opt"], e["L_act"]) for e in episodes] == [(True, steps, steps)]
    assert done.seconds < 60


def test_a_machine_of_100000_states_validates_in_seconds() -> None:
    ssm = msgspec.convert(line_ssm(100_000), replay.StateMachine)
    started = time.monotonic()
    assert replay.semantics.validate_machine(ssm, "big.json") == []
    assert time.monotonic() - started < 20  # a fraction of a second unloaded


def test_immediate_chains_too_long_to_compile_are_refused_before_compiling() -> None:
    """Compiling keeps, for each state and transition, the chain it enters: with 100,000
    chained states, C_i's chain holds 100,000 - i states (99,999 * 100,000 / 2 =
    4,999,950,000 in all), the press into C1 holds C1 and its chain (100,000) and the press
    out of the chain holds Off (1): 5,000,050,001 entries, far past the bound, so validation
    refuses the machine in one problem, in linear time, before anything is built."""
    ssm = msgspec.convert(chain_ssm(100_000), replay.StateMachine)
    started = time.monotonic()
    (problem,) = replay.semantics.validate_machine(ssm, "big.json")
    assert time.monotonic() - started < 20
    assert str(problem) == (
        "big.json [component 'immediate']: immediate chains too long: compiling would hold "
        "5,000,050,001 entered states (at most 16,777,216, PROTOCOL §1.5)"
    )
    with pytest.raises(replay.SSMError, match="immediate chains too long"):
        replay.compile_machine(ssm)
    # 4,000 states stay well within it (7,998,000 + 4,000 + 1 = 8,002,001 entries).
    replay.compile_machine(msgspec.convert(chain_ssm(4000), replay.StateMachine))


def _cycles_by_walking_from_every_state(ssm: replay.StateMachine) -> list[str]:
    """The cycle check as it was (a walk from every state, quadratic per state): the oracle."""
    states = ssm.states
    order = {name: i for i, name in enumerate(states)}
    found = []
    for start in states:
        seen = [start]
        current = start
        while True:
            imm = states[current].on.get("immediate") if current in states else None
            if not imm:
                break
            nxt = imm[0].next_state
            if nxt not in states:
                break
            if nxt in seen:
                members = seen[seen.index(nxt) :]
                if nxt == start and start == min(members, key=order.__getitem__):
                    found.append(f"cycle of immediate transitions: {' -> '.join([*members, nxt])}")
                break
            seen.append(nxt)
            current = nxt
    return found


@settings(max_examples=200, deadline=None)
@given(st.lists(st.integers(-1, 12), min_size=1, max_size=12), st.randoms(use_true_random=False))
def test_cycle_check_matches_the_walk_from_every_state(successors, rng) -> None:
    names = [f"S{i}" for i in range(len(successors))]
    rng.shuffle(names)  # file order differs from the walk order
    states = {}
    for name, nxt in zip(names, successors, strict=True):
        on = {}
        if nxt >= 0:  # a successor past the last state dangles
            on["immediate"] = [{"next_state": f"S{nxt}"}]
        states[name] = {"on": on}
    doc = {"name": "X", "initial_state": names[0], "states": states}
    ssm = msgspec.convert(doc, replay.StateMachine)
    got = [p.message for p in replay.semantics.validate_machine(ssm, "x") if "cycle" in p.message]
    assert got == _cycles_by_walking_from_every_state(ssm)


VIEWS = ("front", "back", "left", "right", "top", "bottom", "dashboard")


def _random_machine(rng: random.Random) -> dict:
    """A small machine with boxes on random views (the dashboard's too), waits, immediate
    transitions and error states: every kind of option the planner weighs."""
    n = rng.randint(2, 7)
    states: dict[str, dict] = {}
    for k in range(n):
        on: dict[str, list[dict]] = {}
        for c in range(rng.randint(0, 3)):
            boxes = [
                {"coordinate": [100 * c, 100 * v, 90, 90, 1000, 1000], "view": view}
                for v, view in enumerate(VIEWS)
                if rng.random() < 0.35
            ]
            on[f"c{c}"] = [
                {"next_state": f"S{rng.randrange(n)}", "atomic_action": "press", "bbox": boxes}
                for _ in range(rng.randint(1, 2))
            ]
        if rng.random() < 0.2:
            on["timed_wait"] = [{"next_state": f"S{rng.randrange(n)}"}]
        if k > 0 and rng.random() < 0.2:  # to an earlier state: never a cycle
            on["immediate"] = [{"next_state": f"S{rng.randrange(k)}"}]
        states[f"S{k}"] = {"on": on, "is_error": rng.random() < 0.15}
    region = {"view": rng.choice(VIEWS[:6]), "coordinate": [800, 800, 100, 100, 1000, 1000]}
    return {
        "name": "R",
        "initial_state": "S0",
        "states": states,
        "dashboard": {"regions": [region]},
    }


@settings(max_examples=150, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_planner_matches_the_recursion(seed: int) -> None:
    """On random machines (every kind of option the planner weighs): the plan, or its
    absence, is the one a plain recursion over every option picks with PROTOCOL §4.3's
    tie-breaks (`tests/replay/plan_oracle.py`), and C_opt from every state is the distance
    plus that recursion's fewest switches."""
    from replay.semantics import INF, c_opt_dynamic, distances, plan_goals

    from ..replay.plan_oracle import NONE, oracle_plan, oracle_switches, plan_steps

    rng = random.Random(seed)
    doc = _random_machine(rng)
    goals = tuple(rng.randrange(len(doc["states"])) for _ in range(rng.randint(1, 3)))
    view = rng.choice(VIEWS[:6])
    machine = replay.compile_machine(msgspec.convert(doc, replay.StateMachine))
    want = oracle_plan(machine, goals, 0, view, False)
    if want is None:
        with pytest.raises(replay.TaskError):
            plan_goals(machine, 0, view, False, goals)
    else:
        assert plan_steps(plan_goals(machine, 0, view, False, goals)) == want
    for s in range(len(doc["states"])):
        d = distances(machine, goals[0])[s]
        fewest = oracle_switches(machine, (goals[0],), 0, s, view, False)
        unreachable = d >= INF or fewest >= NONE  # a transient state may end out of reach
        expected = 0 if s == goals[0] else None if unreachable else d + fewest
        assert c_opt_dynamic(machine, s, view, False, goals[0]) == expected, s


# ------------------------------------------------------------------------------ names


def test_an_episode_id_of_300_characters_gets_a_short_unique_file(tmp_path, vge_here) -> None:
    ids = ["é" * 290 + "/a", "é" * 290 + "/b", "x" * 300, "short/one"]
    root = write_bench(
        tmp_path / "bench", {"press": line_ssm(2)}, [task(i, "press", "S1") for i in ids]
    )
    run = write_run(tmp_path / "run", [episode(i) for i in ids])
    names = []
    for attempt in ("out", "again"):
        done = vge_here("replay", run, "--bench", root, "--out", tmp_path / attempt, "--mcap")
        assert done.returncode == 0, done.stderr
        names.append(sorted(p.name for p in (tmp_path / attempt / "mcap" / "run").iterdir()))
    assert names[0] == names[1]  # the same names on every run
    # PROTOCOL §7.8, by hand: the head holds whole characters within 200 - 1 - 32 = 167
    # bytes, then "=" and 32 hex digits of the id's sha256. "x" encodes to 1 byte: 167 of
    # them, a name of exactly 200 bytes. "é" encodes to 6 ("%C3%A9"): 27 fit (162 bytes; a
    # 28th would make 168), so those names are 162 + 1 + 32 = 195 bytes, never a cut "%C3".
    digest = {i: hashlib.sha256(i.encode()).hexdigest()[:32] for i in ids}
    want = sorted(
        [
            "short%2Fone.mcap",
            "x" * 167 + f"={digest['x' * 300]}.mcap",
            "%C3%A9" * 27 + f"={digest[ids[0]]}.mcap",
            "%C3%A9" * 27 + f"={digest[ids[1]]}.mcap",
        ]
    )
    assert names[0] == want
    assert sorted(len(n.encode()) for n in want) == [16, 200, 200, 205]  # ".mcap" included


def test_a_run_id_that_cannot_name_a_directory_is_refused_in_one_line(
    bench, tmp_path, vge_here
) -> None:
    run = write_run(tmp_path / "run", [episode("e0")], run_id="r" * 300)
    done = vge_here("replay", run, "--bench", bench, "--out", tmp_path / "out")
    assert done.returncode == 1
    assert one_line_error(done.stderr) == (
        f"error: {run / 'run.json'}: run_id is 300 bytes long; it names directories, so at "
        "most 200 bytes (UTF-8)"
    )
    assert not (tmp_path / "out" / "steps").exists()


# -------------------------------------------------------------------------- processes


@pytest.mark.skipif(sys.platform != "linux", reason="reads /proc")
def test_a_killed_replay_leaves_no_process_behind(bench, tmp_path) -> None:
    """`vge replay --workers 2` killed with `kill -9`: its worker ends too. The worker is
    forked (one thread here, on Linux), so no resource tracker is started: a fork's
    semaphores are unlinked as made. The spawned case, with its tracker, is the idle pool's
    test below."""
    run = write_run(tmp_path / "run", (padded(f"e{i}", 100_000) for i in range(GOOD)))
    cmd = [*VGE, "replay", str(run), "--bench", str(bench), "--out", str(tmp_path / "out")]
    proc = subprocess.Popen([*cmd, "--workers", "2"], stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 300  # a wait: Python starting, slow on a busy machine
        while not children(proc.pid) and time.monotonic() < deadline:
            time.sleep(0.05)
        kids = children(proc.pid)  # the worker, forked (no resource tracker: see the docstring)
        assert len(kids) == 1 and proc.poll() is None
    finally:
        proc.kill()
        proc.wait()
    assert left_after(kids, 15) == []


_IDLE_POOL = """
import functools, os, sys, time
from concurrent.futures import ProcessPoolExecutor
import multiprocessing
from replay.io._lifetime import end_with_parent
if __name__ == "__main__":
    init = functools.partial(end_with_parent, death_signal=sys.argv[1] == "signal")
    pool = ProcessPoolExecutor(1, multiprocessing.get_context("spawn"), init, (os.getpid(),))
    print(pool.submit(os.getpid).result(), flush=True)  # then idle, waiting for tasks
    time.sleep(120)
"""


@pytest.mark.skipif(sys.platform != "linux", reason="reads /proc")
@pytest.mark.parametrize("how", ["signal", "watch"])
def test_an_idle_worker_ends_with_its_parent(how: str) -> None:
    """A worker waiting for tasks when its parent is killed: before, it (and the resource
    tracker) waited for ever; now the kernel's death signal, or its watch thread, ends it."""
    proc = subprocess.Popen(
        [sys.executable, "-c", _IDLE_POOL, how], stdout=subprocess.PIPE, text=True
    )
    try:
        worker = int(proc.stdout.readline())  # type: ignore[union-attr]
        kids = children(proc.pid)
        assert worker in kids and len(kids) == 2
    finally:
        proc.kill()
        proc.wait()
    assert left_after(kids, 15) == []


@pytest.mark.parametrize(
    "where", ["staging", "trash", "staging/run", "trash/steps-run_id=run", "dangling staging"]
)
def test_stale_links_in_the_replay_state_are_unlinked_never_followed(
    bench, tmp_path, where
) -> None:
    run = write_run(tmp_path / "run", [episode("e0")])
    out = tmp_path / "out"
    assert replay.replay_runs([run], bench, out, progress=False).exit_code == 0
    elsewhere = tmp_path / "elsewhere"
    (elsewhere / "steps-run_id=run").mkdir(parents=True)
    (elsewhere / "keep.txt").write_text("not the replay's")
    link = out / ".replay" / where.removeprefix("dangling ")
    link.parent.mkdir(parents=True, exist_ok=True)
    link.symlink_to(tmp_path / "nowhere" if where.startswith("dangling") else elsewhere)
    manifest = replay.replay_runs([run], bench, out, force=True, progress=False)
    assert manifest.exit_code == 0 and manifest.replayed == ["run"]
    assert not link.is_symlink()
    assert sorted(p.name for p in elsewhere.iterdir()) == ["keep.txt", "steps-run_id=run"]


# ------------------------------------------------------------------ appended bytes


_TAIL = st.lists(
    st.one_of(
        st.binary(max_size=60),
        st.sampled_from([b"\n", b"\r\n", b"{", b"}", b"[", b'"', b"\\", b"\x00", b"\xff"]),
        st.builds(
            lambda eid, steps: json.dumps({"episode_id": eid, "steps": steps}).encode(),
            st.sampled_from(["e0", "e1", "e5", "e9", "zz"]),
            st.lists(
                st.one_of(
                    st.fixed_dictionaries({"output": st.text(max_size=40)}),
                    st.fixed_dictionaries(
                        {
                            "action": st.fixed_dictionaries(
                                {
                                    "type": st.sampled_from(["Press", "Switch_view", "Nope"]),
                                    "coord": st.one_of(
                                        st.none(),
                                        st.lists(st.floats(-1e308, 1e308), max_size=3),
                                    ),
                                    "params": st.lists(st.text(max_size=5), max_size=2),
                                }
                            )
                        }
                    ),
                    st.integers(),
                ),
                max_size=4,
            ),
        ),
    ),
    max_size=8,
).map(b"".join)


def _rows(out: Path, table: str) -> pa.Table:
    parts = sorted((out / table / "run_id=run").iterdir())
    return pa.concat_tables([pq.read_table(p) for p in parts])


@pytest.fixture(scope="module")
def valid_log(bench: Path, tmp_path_factory: pytest.TempPathFactory):
    """Four valid records, each line with its newline, and their replay alone."""
    root = tmp_path_factory.mktemp("valid")
    lines = [
        episode("e0"),
        episode("e1", 3),
        episode("e2", output="Action: Wait()"),
        episode("e3", 0),
    ]
    data = b"".join(line + b"\n" for line in lines)
    run = write_run(root / "run", [])
    (run / "episodes.jsonl").write_bytes(data)
    out = root / "out"
    assert replay.replay_runs([run], bench, out, progress=False).exit_code == 0
    return data, {t: _rows(out, t) for t in ("steps", "episodes", "goals")}


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(tail=_TAIL, gz=st.booleans())
def test_appended_bytes_never_change_the_records_before_them(
    bench, valid_log, tmp_path, tail: bytes, gz: bool
) -> None:
    """Whatever bytes follow a valid log (after the newline of its last line), the replay
    ends with 0 or 2, never 1, and the records before them replay as they did alone: the
    first rows of every table are theirs, unchanged, and no quarantine record names one of
    their lines. (Appended to a .gz file, the bytes follow its compressed stream.) Without
    that newline the bytes would extend the last valid line, which is then another line."""
    data, alone = valid_log
    run = write_run(tmp_path / "run", [], gz=gz)
    name = "episodes.jsonl.gz" if gz else "episodes.jsonl"
    (run / name).write_bytes((gzip.compress(data, mtime=0) if gz else data) + tail)
    out = tmp_path / "out"
    manifest = replay.replay_runs([run], bench, out, progress=False, max_record_bytes=4096)
    assert manifest.exit_code in (0, 2)
    for table, rows in alone.items():
        got = _rows(out, table)
        assert got.slice(0, rows.num_rows).equals(rows), table
    assert all(line > 4 for line, _ in quarantine(out))


# ---------------------------------------------------------------------- the responses


@pytest.mark.parametrize(
    "text",
    [
        "action:" * 300_000,
        "-" * 2_000_000 + "action:" * 300_000,
        ("x\n" + "action:" * 10) * 30_000,
        "Thinking: " + " action" * 300_000 + "\nAction: Press(coord=[500, 500])",
    ],
    ids=["labels", "decorated labels", "labels on many lines", "label words"],
)
def test_responses_full_of_labels_parse_in_linear_time(text: str) -> None:
    """Looking for the line of each `Action:` label from its start made the parsers
    quadratic: 350 KB of labels took 86 s in the reference and 3 s in the kernel."""
    from replay.kernel._text import parse_fields

    for parse in (replay.parse_action, parse_fields):
        started = time.monotonic()
        parse(text)
        assert time.monotonic() - started < 10, parse  # 0.2 s here; hours if quadratic
