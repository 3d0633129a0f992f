"""The compiled kernel (`replay.kernel`) gives exactly the reference engine's tables.

`replay_episode` is the reference. Compared table against table (`pa.Table.equals`): the
bundled sample, every hand-worked case, hypothesis-generated logs (well-formed and broken
texts, structured actions, switches and dashboard unlocks, waits, out-of-range points,
recorded values that match or not, timestamps, logs longer than the budget, small
lambdas) on the hand-worked SSMs and a few sample SSMs; the compiled parser against
`parse_action` on arbitrary texts; and the runner's files with either engine.
"""

from __future__ import annotations

import gzip
import hashlib
import json
from functools import cache
from pathlib import Path

import msgspec
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import replay
from replay.io import episode_decoder, reference_tables
from replay.kernel import EpisodeInput, parse_fields, replay_kernel
from replay.semantics import (
    ACTION_NAMES,
    FEEDBACK_KINDS,
    STANDARD_VIEWS,
    normalize_param,
    parse_action,
    setup_episode,
)

ROOT = Path(__file__).resolve().parents[3]
DATA = ROOT / "tests" / "data"
CASES = DATA / "hand_worked"
LOGS = ROOT / "logs"


# ------------------------------------------------------------------------------ helpers


def first_difference(got: pa.Table, want: pa.Table) -> str:
    """Where two tables differ: the first column and row, for the failure message."""
    if got.schema != want.schema:
        return f"schemas differ:\n{got.schema}\nvs\n{want.schema}"
    if got.num_rows != want.num_rows:
        return f"{got.num_rows} rows, expected {want.num_rows}"
    for name in want.column_names:
        a, b = got[name], want[name]
        if a.equals(b):
            continue
        for i, (x, y) in enumerate(zip(a.to_pylist(), b.to_pylist(), strict=True)):
            if x != y or type(x) is not type(y) or repr(x) != repr(y):
                return f"column {name!r}, row {i}: kernel {x!r}, reference {y!r}"
        return f"column {name!r}: same values, different nulls or chunks"
    return "tables differ"


def assert_same(got: pa.Table, want: pa.Table, what: str) -> None:
    assert got.equals(want), f"{what}: {first_difference(got, want)}"


def scalar_tables(episodes: list[EpisodeInput], head=("run", "model", "vlm")):
    return reference_tables(scalar_results(episodes, head))


def scalar_results(
    episodes: list[EpisodeInput], head=("run", "model", "vlm")
) -> list[replay.EpisodeResult]:
    return [
        replay.replay_episode(
            e.machine,
            e.task,
            e.log,
            lam=e.lam,
            run_id=head[0],
            model=head[1],
            agent_kind=head[2],
            setup=e.setup,
        )
        for e in episodes
    ]


def check_batch(episodes: list[EpisodeInput]) -> None:
    """The kernel's tables of a batch equal the reference ones, row counts included, and
    its rows read back per episode (what the MCAP writer gets) encode to the reference's
    JSON, byte for byte (an int where a float is due would show)."""
    results = scalar_results(episodes)
    steps, eps, goals, step_counts, goal_counts = reference_tables(results)
    got = replay_kernel(episodes, run_id="run", model="model", agent_kind="vlm")
    assert_same(got.steps, steps, "steps")
    assert_same(got.episodes, eps, "episodes")
    assert_same(got.goals, goals, "goals")
    assert list(got.step_counts) == step_counts and list(got.goal_counts) == goal_counts
    mine = got.episode_results(list(range(len(episodes))))
    for j, (a, b) in enumerate(zip(mine, results, strict=True)):
        assert _json(a) == _json(b), f"episode {j}: rows read back differ from the reference's"


def _json(result: replay.EpisodeResult) -> list[bytes]:
    encode = msgspec.json.encode
    return [encode(result.episode), *map(encode, result.steps), *map(encode, result.goals)]


@cache
def machine_of(path: Path, device_id: str) -> replay.Machine:
    return replay.compile_machine(replay.load_ssm(path), device_id=device_id)


def episode(machine, task, steps: list[dict], lam: float) -> EpisodeInput:
    log = msgspec.convert({"episode_id": task.episode_id, "steps": steps}, replay.EpisodeLog)
    return EpisodeInput(machine, task, setup_episode(machine, task), log, lam)


# ------------------------------------------------------------------ fixed inputs


def _case_docs() -> list[dict]:
    docs = []
    for path in sorted(CASES.glob("*.json")):
        doc = json.loads(path.read_text())
        if isinstance(doc, dict) and "expected" in doc:
            docs.append(doc)
    return docs


def _ssm_file(name: str) -> Path:
    return CASES / name if (CASES / name).exists() else DATA / name


@pytest.mark.parametrize("doc", _case_docs(), ids=lambda d: d["task"]["episode_id"])
def test_hand_worked_cases(doc: dict) -> None:
    machine = machine_of(_ssm_file(doc["ssm"]), doc["device_id"])
    task = msgspec.convert(doc["task"], replay.Task)
    check_batch([episode(machine, task, doc["episode"]["steps"], float(doc["lambda"]))])


def test_hand_worked_cases_in_one_batch() -> None:
    """All cases at once, each twice (per-machine tables are reused across episodes), and
    each once more with an empty log."""
    batch = []
    for doc in _case_docs() * 2:
        machine = machine_of(_ssm_file(doc["ssm"]), doc["device_id"])
        task = msgspec.convert(doc["task"], replay.Task)
        batch.append(episode(machine, task, doc["episode"]["steps"], float(doc["lambda"])))
        batch.append(episode(machine, task, [], float(doc["lambda"])))
    check_batch(batch)


def test_empty_batch() -> None:
    check_batch([])


def _sample_batches(size: int):
    bench = replay.Benchmark.open(LOGS / "bench")
    for run in sorted((LOGS / "runs").iterdir()):
        header = replay.read_run_header(run)
        path = replay.episodes_file(run)
        data = path.read_bytes()
        lines = (gzip.decompress(data) if path.suffix == ".gz" else data).splitlines()
        batch: list[EpisodeInput] = []
        for line in lines:
            if not line.strip():
                continue
            log = episode_decoder.decode(line)
            task = bench.tasks[log.episode_id].task
            machine = bench.machine(task.device_id)
            lam = task.lam if task.lam is not None else header.lam
            batch.append(EpisodeInput(machine, task, setup_episode(machine, task), log, lam or 5))
            if len(batch) == size:
                yield run.name, batch
                batch = []
        if batch:
            yield run.name, batch


def test_bundled_sample() -> None:
    """Every run of `logs/`, in batches of 200 episodes (machine tables kept, as a worker)."""
    for run, batch in _sample_batches(200):
        try:
            check_batch(batch)
        except AssertionError as exc:
            raise AssertionError(f"run {run}: {exc}") from None


# ------------------------------------------------------------------ generated logs

_SAMPLE_DEVICES = ("AirFryer_000", "CoffeeMachine_000", "CarKey_000")


@cache
def _machines() -> list[tuple[replay.Machine, list[replay.Task]]]:
    """Machines with tasks that set up: the hand-worked SSMs, a few sample SSMs (one of
    them with a dashboard)."""
    out: dict[str, tuple[replay.Machine, list[replay.Task]]] = {}
    for doc in _case_docs():
        machine = machine_of(_ssm_file(doc["ssm"]), doc["device_id"])
        out.setdefault(doc["device_id"], (machine, []))[1].append(
            msgspec.convert(doc["task"], replay.Task)
        )
    bench = replay.Benchmark.open(LOGS / "bench")
    devices = list(_SAMPLE_DEVICES)
    devices += [d for d in sorted(bench.ssm_paths) if bench.machine(d).has_dashboard][:1]
    for device in devices:
        tasks = [e.task for e in bench.tasks.values() if e.task.device_id == device][:4]
        out[device] = (bench.machine(device), tasks)
    return list(out.values())


def _points(machine: replay.Machine) -> list[tuple[float, float]]:
    """Points that matter: centres, corners and just-outside of every rect and region."""
    points = []
    rects = [r for pairs in machine.component_rects.values() for _, r in pairs]
    rects += [r for regions in machine.dashboard_regions.values() for r in regions]
    for x0, y0, x1, y1, _ in rects:
        points += [((x0 + x1) / 2, (y0 + y1) / 2), (x0, y0), (x1, y1), (x1 + 0.5, y0)]
    return points or [(500.0, 500.0)]


def _number(v: float) -> str:
    return str(int(v)) if v == int(v) else f"{v:.2f}"


@st.composite
def _step(draw, machine: replay.Machine) -> dict:
    views = list(machine.views) + ["dashboard", "Top", "sideways"]
    params_pool = sorted(
        {p for t in machine.transitions for p in (t.params or ())} | {"0", "1", "*", "x y"}
    )
    kind = draw(st.sampled_from(["Press", "Rotate", "Push", "Pull", "Grasp", "Switch_view",
                                 "Timed_wait", "press", "Tap"]))  # fmt: skip
    point = draw(
        st.sampled_from(_points(machine))
        | st.tuples(st.integers(-50, 1050), st.integers(-50, 1050)).map(
            lambda p: (float(p[0]), float(p[1]))
        )
        | st.none()
    )
    if kind == "Switch_view":
        params = [draw(st.sampled_from(views))]
    else:
        params = draw(st.lists(st.sampled_from(params_pool), max_size=2))
    step: dict = {}
    shape = draw(st.sampled_from(["text", "text", "text", "structured", "odd", "empty"]))
    if shape == "structured":
        step["action"] = {
            "type": kind,
            "coord": None if point is None else list(point),
            "params": params,
        }
    elif shape == "text" or shape == "odd":
        args = []
        if point is not None:
            args.append(f"coord=[{_number(point[0])}, {_number(point[1])}]")
        if params or kind != "Timed_wait":
            quote = draw(st.sampled_from(["", "'", '"']))
            args.append("params=[" + ", ".join(quote + p + quote for p in params) + "]")
        call = f"{kind}({', '.join(args)})"
        thinking = draw(
            st.sampled_from(["I press it.", "Température 200 °C.", "  spaced\u00a0", "", "x\x1c"])
        )
        label = draw(st.sampled_from(["\nAction: ", "\n**Action:** ", "\nAction:", " Action: "]))
        if shape == "odd":
            call = draw(
                st.sampled_from(
                    [
                        call.replace(", ", " "),  # malformed
                        call + "\nAction: Timed_wait()",  # multiple actions
                        "`" + call + "`.",
                        call.replace("(", " ("),
                        "",
                    ]
                )
            )
        step["output"] = f"Thinking: {thinking}{label}{call}"
    if draw(st.booleans()):
        step["feedback"] = draw(st.sampled_from([*FEEDBACK_KINDS, "Nothing happened.", "odd"]))
    if draw(st.booleans()):
        step["state"] = draw(st.sampled_from([*machine.states, "Nowhere"]))
    if draw(st.booleans()):
        step["view"] = draw(st.sampled_from([*STANDARD_VIEWS, "FRONT", "dashboard"]))
    if draw(st.booleans()):
        step["timestamp"] = draw(
            st.sampled_from([1_700_000_000.5, 1_700_000_001, "2026-01-02T03:04:05Z", "soon"])
        )
    return step


@st.composite
def _episodes(draw) -> list[EpisodeInput]:
    """1-4 episodes on random machines; steps biased towards what the plan would do, so
    goals complete and budgets run out (logs longer than the budget are truncated)."""
    out = []
    for _ in range(draw(st.integers(1, 4))):
        machine, tasks = draw(st.sampled_from(_machines()))
        task = draw(st.sampled_from(tasks))
        setup = setup_episode(machine, task)
        steps = []
        for planned in setup.plan.steps:
            if draw(st.integers(0, 3)) == 0:  # detours
                steps += draw(st.lists(_step(machine), max_size=3))
            a = planned.action
            coord = None if a.coord is None else list(a.coord)
            steps.append({"action": {"type": a.type, "coord": coord, "params": list(a.params)}})
        steps += draw(st.lists(_step(machine), max_size=12))
        lam = draw(st.sampled_from([0.3, 0.7, 1.0, 1.5, 2.5, 5.0]))
        out.append(episode(machine, task, steps, lam))
    return out


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_episodes())
def test_generated_logs(episodes: list[EpisodeInput]) -> None:
    check_batch(episodes)


# ------------------------------------------------------------------ the batch parser

_FRAGMENTS = st.sampled_from(
    [
        "Thinking:", "thinking: ", "Action:", "ACTION:", "action", "\nAction: ",
        "\n**Action:** ", "\n> Action:", "**", "`", "```", "\n", " ", "\t", "\u00a0", "\x1c",
        "İ", "ı", "°C", "Press(coord=[1, 2], params=[0])", "Switch_view(params=[top])",
        "Timed_wait()", "Tap(coord=[3, 4])", "Rotate(coord=[5.5, -6], params=['1', \"2\"])",
        "Push(coord=[7 8])", "Pull(params=[a b])", "Grasp(coord=[1, 2], params=[0]).",
        "Press(coord=[1, 2], params=[0,])", "PRESS( coord = [ 9 , 9 ] )", "Transaction:",
        "_Tap(coord=[1, 2])", "Tap()", "Foo(params=[a])", "Tap(coord=[1, 2], params=['x'])",
        "press_it(coord=[1, 2], params=[0])", "Timed_wait(params=[])", "Press(params=[1 2])",
        # pieces of the full grammar and text outside ASCII
        "coord=", "coords = ", "params=", "param=", "(", ")", "[", "]", ",", "'", '"', "=",
        "1e5", ".5", "-0", "7.", "Press", "press(", "rotate (", "Click(", "é", "’", "\u2003",
        "ſ", "\u212a", "٣", "`Rotate(coord=(1, 2), params=['a b', \"c\"])`", "\n```json\n",
    ]
)  # fmt: skip


@settings(max_examples=1000, deadline=None)
@given(st.lists(_FRAGMENTS | st.text(max_size=3), max_size=12).map("".join))
def test_compiled_parser_matches_the_reference(text: str) -> None:
    """Whatever the compiled parser decides, the reference parser decides the same."""
    for candidate in (text, "Thinking: " + text):
        got = parse_fields(candidate)
        if got is None:  # left to the reference
            continue
        want = parse_action(candidate)
        status, kind, coord, params, action_text, thinking = got
        if status == "ok":
            assert want.ok and want.action.type == ACTION_NAMES[kind], candidate
            assert want.action.coord == coord, candidate
            assert tuple(normalize_param(p) for p in params) == want.action.params, candidate
        else:
            assert not want.ok and want.detail == status, candidate
        assert (action_text, thinking) == (want.action_text, want.thinking), candidate


def test_compiled_parser_decides_the_common_shapes() -> None:
    """The shapes of nearly every response are decided without the reference parser."""
    assert parse_fields("Thinking: ok.\nAction: Press(coord=[1, 2], params=[0])") == (
        "ok",
        0,
        (1.0, 2.0),
        ("0",),
        "Press(coord=[1, 2], params=[0])",
        "ok.",
    )
    assert parse_fields("Thinking: no.\nAction: `Switch_view(params=['top'])`.") == (
        "ok",
        5,
        None,
        ("top",),
        "Switch_view(params=['top'])",
        "no.",
    )
    assert parse_fields("I will wait.") == ("no_action", None, None, (), "", "I will wait.")
    assert parse_fields("Action: Timed_wait()\nAction: Press()")[0] == "multiple_actions"


# ------------------------------------------------------------------ the runner's files


def _digests(out: Path) -> dict[str, str]:
    return {
        str(p.relative_to(out)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(out.rglob("*"))
        if p.is_file() and p.suffix in (".parquet", ".json", ".jsonl")
    }


def test_runner_files_identical_with_either_engine(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Small Parquet pages, so that pages split inside row groups: the files do not depend
    on the engine."""
    real = pq.write_table

    def small_pages(*args, **kwargs):
        return real(*args, data_page_size=4096, **kwargs)

    monkeypatch.setattr("replay.io._files.pq.write_table", small_pages)
    monkeypatch.setattr("replay.io._job.BATCH_LINES", 64)
    runs = sorted(str(p) for p in (LOGS / "runs").iterdir())[:3]
    outs = {}
    for engine in ("reference", "kernel"):
        monkeypatch.setattr("replay.io._batch.KERNEL", engine == "kernel")
        replay.replay_runs(runs, LOGS / "bench", tmp_path / engine, progress=False)
        outs[engine] = _digests(tmp_path / engine)
    assert outs["reference"] == outs["kernel"]
    assert sum(name.endswith(".parquet") for name in outs["kernel"]) > 3 * 3


def test_runner_files_identical_with_any_number_of_workers(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr("replay.io._job.BATCH_LINES", 64)
    runs = sorted(str(p) for p in (LOGS / "runs").iterdir())[:3]
    outs = []
    for workers in (1, 2):
        out = tmp_path / str(workers)
        replay.replay_runs(runs, LOGS / "bench", out, workers=workers, progress=False)
        outs.append(_digests(out))
    assert outs[0] == outs[1]


# ------------------------------------------------------------------ edge cases


def _wide_machine(n_components: int) -> replay.Machine:
    """Two states, each with `n_components` 10x10 buttons on the front view."""
    from ..machines import box, machine, tr

    on = {
        f"c{i:02d}": [
            tr(
                "B" if i % 2 == 0 else "A",
                boxes=[box("front", 10 * (i % 90), 10 * (i // 90), 9, 9)],
            )
        ]
        for i in range(n_components)
    }
    return machine({"A": on, "B": on}, "A")


def test_wide_machines_and_extreme_budgets() -> None:
    """A machine with 70 components, and budgets with lambda 1e17 and 0.5, among others."""
    wide = _wide_machine(70)
    wide_task = replay.Task(episode_id="wide", device_id="dev", goals=["B"])
    doc = _case_docs()[0]
    kettle = machine_of(_ssm_file(doc["ssm"]), doc["device_id"])
    task = msgspec.convert(doc["task"], replay.Task)
    press = [{"output": "Thinking: a.\nAction: Press(coord=[4, 4], params=[0])"}] * 3
    batch = [
        episode(kettle, task, doc["episode"]["steps"], 5.0),
        episode(wide, wide_task, press, 5.0),
        episode(kettle, task, doc["episode"]["steps"], 1e17),
        episode(kettle, task, doc["episode"]["steps"], 0.5),
    ]
    check_batch(batch)


def test_non_finite_coordinates_are_malformed_in_both_engines() -> None:
    """`1e999` (or hundreds of digits) is no coordinate: a parse failure (`malformed`)."""
    doc = _case_docs()[0]
    kettle = machine_of(_ssm_file(doc["ssm"]), doc["device_id"])
    task = msgspec.convert(doc["task"], replay.Task)
    steps = [
        {"output": "Thinking: far.\nAction: Press(coord=[1e999, 5], params=[0])"},
        {"output": "Thinking: far.\nAction: Press(coord=[" + "9" * 400 + ", 5], params=[0])"},
        {"output": "Thinking: far.\nAction: Press(coord=[1e300, -0], params=[0])"},
    ]
    batch = [episode(kettle, task, steps, 5.0)]
    check_batch(batch)
    table = scalar_tables(batch)[0]
    assert table.column("parse_detail").to_pylist() == ["malformed", "malformed", None]
