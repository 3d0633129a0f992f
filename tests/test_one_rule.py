"""Each rule of PROTOCOL that used to be stated in several places is now one public name in
`replay`, and every former caller goes through it (docs/ARCHITECTURE.md, "Where each rule
lives"). Behaviour where a caller can be observed, the source where only its absence of a
copy can be: a literal or a restated rule in a former caller fails here."""

from __future__ import annotations

import ast
import io
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory
from PIL import Image

import replay
import vge_analytics as va
from replay.env import DeviceEnv
from replay.io import RunDirectory
from vge_analytics import dashboard as dash
from vge_analytics.synth import image_source

ROOT = Path(__file__).resolve().parents[1]
KETTLE = ROOT / "tests" / "data" / "kettle_ssm.json"
RED, BLUE = (200, 30, 30), (30, 30, 200)


def _png(size: tuple[int, int], color: tuple[int, int, int]) -> bytes:
    buf = io.BytesIO()
    Image.new("RGB", size, color).save(buf, format="PNG")
    return buf.getvalue()


def _source(tree: str) -> list[tuple[Path, ast.AST]]:
    return [(p, ast.parse(p.read_text())) for p in sorted((ROOT / tree).rglob("*.py"))]


# ------------------------------------------------------------------- image (§1.1)


@pytest.fixture
def pictured(tmp_path: Path) -> dict:
    """A kettle benchmark whose front view has a file (red, 64 x 48) and an SSM `images`
    entry (blue, 30 x 20), replayed with MCAP through the analytics' image source."""
    bench = tmp_path / "bench"
    (bench / "ssm").mkdir(parents=True)
    ssm = json.loads(KETTLE.read_text())
    ssm["images"] = {"front": {"path": "declared/front.png", "width": 30, "height": 20}}
    (bench / "ssm" / "kettle.json").write_text(json.dumps(ssm))
    (bench / "declared").mkdir()
    (bench / "declared" / "front.png").write_bytes(_png((30, 20), BLUE))
    (bench / "images" / "kettle").mkdir(parents=True)
    (bench / "images" / "kettle" / "front.png").write_bytes(_png((64, 48), RED))
    task = {"episode_id": "e1", "device_id": "kettle", "goals": ["Boiling"], "initial_view": "front"}
    (bench / "tasks.jsonl").write_text(json.dumps(task) + "\n")
    run = tmp_path / "run"
    run.mkdir()
    (run / "run.json").write_text(json.dumps({"run_id": "r", "model": "m", "agent_kind": "vlm"}))
    step = {"output": "Thinking: wait.\nAction: Timed_wait()"}
    (run / "episodes.jsonl").write_text(json.dumps({"episode_id": "e1", "steps": [step]}) + "\n")
    return {"bench": bench, "run": run, "out": tmp_path / "out"}


def _camera_frames(out: Path) -> list[bytes]:
    path = replay.episode_mcap_path(out, "r", "e1").local
    with open(path, "rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        return [m.data for _, _, _, m in reader.iter_decoded_messages(topics=["/camera"])]


def _observed(bench: Path) -> np.ndarray:
    env = DeviceEnv(bench, image_source=image_source(bench), image_width=64, image_height=48)
    obs, _ = env.reset(options={"episode_id": "e1"})
    return obs["image"]


def _sides(pictured: dict) -> tuple[bytes, bytes, np.ndarray]:
    """The front view as the MCAP frame, the dashboard's picture and the environment show it."""
    bench, out = pictured["bench"], pictured["out"]
    replay.replay_runs(
        [pictured["run"]], bench, out, mcap=True, image_source=image_source(bench), force=True,
        progress=False,
    )  # fmt: skip
    (frame,) = _camera_frames(out)
    va.clear_cache()
    picture = dash.view_picture(out, "kettle", "front")
    return frame, picture.data, _observed(bench)


def test_the_mcap_the_dashboard_and_the_environment_show_one_picture(pictured) -> None:
    """The file wins over the SSM's entry everywhere (it used to win only in the dashboard;
    the MCAP writer took the SSM's entry first), then the entry, again everywhere."""
    frame, picture, observed = _sides(pictured)
    assert frame == picture == (pictured["bench"] / "images/kettle/front.png").read_bytes()
    assert tuple(observed[0, 0]) == RED
    (pictured["bench"] / "images/kettle/front.png").unlink()
    frame, picture, observed = _sides(pictured)
    assert frame == picture == (pictured["bench"] / "declared/front.png").read_bytes()
    assert tuple(observed[0, 0]) == BLUE  # 30 x 20 resized to 64 x 48: still blue


def test_an_unreadable_or_oversized_picture_counts_as_absent(tmp_path, pictured) -> None:
    bench = pictured["bench"]
    machine = replay.load_machine(bench / "ssm" / "kettle.json")
    (bench / "images/kettle/front.png").write_bytes(b"not a picture")
    assert replay.bench_image(bench, machine, "front").data == _png((30, 20), BLUE)
    (bench / "declared/front.png").write_bytes(b"\0" * (replay.MAX_IMAGE_BYTES + 1))
    assert replay.bench_image(bench, machine, "front") is None


# --------------------------------------------------------------------- λ (§3.5)


def test_every_reader_of_lambda_takes_the_tasks_own_first(tmp_path, pictured) -> None:
    """A task with λ 2 in a run of λ 3: the replay, the environment and the dashboard's
    episode file use 2; `--lambda 4` wins over both in the replay; the runs table shows the
    run's."""
    tasks = pictured["bench"] / "tasks.jsonl"
    task = json.loads(tasks.read_text()) | {"lambda": 2}
    tasks.write_text(json.dumps(task) + "\n")
    header = pictured["run"] / "run.json"
    header.write_text(json.dumps(json.loads(header.read_text()) | {"lambda": 3}))
    out = pictured["out"]
    bench = pictured["bench"]
    replay.replay_runs(
        [pictured["run"]], bench, out, mcap=True, image_source=image_source(bench), progress=False
    )
    assert va.episodes(out)["lambda"].to_list() == [2.0]
    assert va.runs(out)["lambda"].to_list() == [3.0]
    env = DeviceEnv(pictured["bench"], lam=3, image_source=replay.env.no_images)
    env.reset(options={"episode_id": "e1"})
    assert env.session.budget.lam == 2.0
    written = replay.episode_mcap_path(out, "r", "e1").local.read_bytes()
    replay.episode_mcap_path(out, "r", "e1").local.unlink()
    assert dash.episode_mcap(out, "r", "e1") == written  # made again, under the same λ
    replay.replay_runs([pictured["run"]], pictured["bench"], tmp_path / "o4", lam=4, progress=False)
    assert va.episodes(tmp_path / "o4")["lambda"].to_list() == [4.0]


def test_the_lambda_and_budget_rules_are_stated_once() -> None:
    """Outside `replay/semantics/_budget.py` nobody picks among λs or refills a budget: the
    default λ is read there only, the refill and the termination rule are called there only."""
    allowed = {"_budget.py", "_vocab.py", "__init__.py"}
    for tree in ("replay", "vge_analytics", "app"):
        for path, node in _source(tree):
            if path.name in allowed and path.parent.name in ("semantics", "replay"):
                continue
            names = {n.id for n in ast.walk(node) if isinstance(n, ast.Name)} | {
                n.attr for n in ast.walk(node) if isinstance(n, ast.Attribute)
            }
            for rule in ("DEFAULT_LAMBDA", "refreshed_budget", "termination_after"):
                assert rule not in names, f"{path.relative_to(ROOT)} restates {rule}"


@pytest.mark.parametrize("lam", [1.5, 5.0])
def test_the_synthetic_agent_plays_under_the_replays_budget(lam: float) -> None:
    """The simulated agent counts its budget with `replay.Budget` under `episode_lambda`: at
    any λ its log ends exactly where the replay of the log ends (no step left unscored, none
    cut off as `log_ended`)."""
    import random

    from vge_analytics.synth import PROFILES, TaskRecord, load_catalog, play_episode

    bench = replay.Benchmark.open(ROOT / "logs" / "bench")
    profile = next(p for p in PROFILES if p.name == "sim-vlm-c")
    for episode_id in list(bench.tasks)[:20]:
        task = bench.tasks[episode_id].task
        machine = bench.machine(task.device_id)
        record = TaskRecord(
            task.episode_id, task.device_id, tuple(task.goals), tuple(task.instructions),
            task.initial_view, tuple(task.c_opt or ()),
        )  # fmt: skip
        steps = play_episode(
            machine, load_catalog(machine.category), profile, record, random.Random(7), lam
        )
        log = replay.EpisodeLog(
            episode_id=episode_id,
            steps=[
                replay.LogStep(output=s.output)
                if s.record is None
                else replay.LogStep(action=replay.ActionRecord(**s.record))
                for s in steps
            ],
        )
        episode = replay.replay_episode(
            machine, task, log, lam=replay.episode_lambda(task, lam), run_id="r", model="m",
            agent_kind="vlm",
        ).episode  # fmt: skip
        assert episode.termination != "log_ended" and episode.truncated_steps == 0
        assert episode.n_steps == len(steps) and episode.lam == lam


# ---------------------------------------------------------- scale and vocabulary


FORMER_CALLERS = [
    "replay/semantics/_machine.py",
    "replay/semantics/_step.py",
    "replay/io/_mcap.py",
    "vge_analytics/play/_clicks.py",
    "vge_analytics/synth/_agent.py",
    "vge_analytics/synth/_geometry.py",
    "vge_analytics/dashboard/_pictures.py",
    "app/_charts.py",
]


@pytest.mark.parametrize("name", FORMER_CALLERS)
def test_the_scale_and_the_vocabulary_are_named_not_restated(name: str) -> None:
    """No 1000 (the coordinate scale, `replay.SCALE`) and no view or action name literal
    (`replay.DASHBOARD`, `AXONOMETRIC_VIEWS`, `DISPLAY_NAMES`, ...) in the files that used
    to declare their own."""
    node = ast.parse((ROOT / name).read_text())
    words = {"dashboard", "front_top", "back_bottom", "Switch_view", "Timed_wait", "Press"}
    for n in ast.walk(node):
        if isinstance(n, ast.Constant) and not isinstance(n.value, bool):
            assert n.value not in (1000, 1000.0), f"{name}:{n.lineno}: the scale as a number"
            assert n.value not in words, f"{name}:{n.lineno}: {n.value!r} restated"


# ----------------------------------------------------------- run directory (§10.2)


class _Spy:
    def __init__(self, monkeypatch) -> None:
        self.headers: list[Path] = []
        self.lines: list[Path] = []
        write_header, append, stream = (
            RunDirectory.write_header, RunDirectory.append, RunDirectory.stream
        )  # fmt: skip

        def header(rundir, h):
            self.headers.append(rundir.root)
            return write_header(rundir, h)

        def line(rundir, data):
            self.lines.append(rundir.root)
            return append(rundir, data)

        def streamed(rundir, **kw):
            self.lines.append(rundir.root)
            return stream(rundir, **kw)

        monkeypatch.setattr(RunDirectory, "write_header", header)
        monkeypatch.setattr(RunDirectory, "append", line)
        monkeypatch.setattr(RunDirectory, "stream", streamed)


def test_synth_run_and_play_write_run_directories_through_one_writer(tmp_path, monkeypatch) -> None:
    from vge_analytics.cli import main
    from vge_analytics.play import HumanRun
    from vge_analytics.synth import generate

    spy = _Spy(monkeypatch)
    generate(tmp_path / "synth", scale="tiny", seed=0, workers=1)
    made = {p.parent.name for p in spy.headers}
    assert {p.name for p in (tmp_path / "synth" / "runs").iterdir()} <= {p.name for p in spy.headers}
    assert made == {"runs"}
    spy.headers.clear()
    bench = tmp_path / "synth" / "bench"
    assert main(["run", str(bench), "--agent", "sim:f", "--limit", "2", "--out", str(tmp_path / "live")]) == 0
    assert spy.headers[-1] == tmp_path / "live" and tmp_path / "live" in spy.lines
    spy.headers.clear()
    human = HumanRun.open(tmp_path / "human", bench, image_source=replay.env.no_images, clock=None)
    assert spy.headers == [tmp_path / "human"]
    play = human.start(human.next_episode())
    while not play.done:
        play.act({"type": "Timed_wait", "coord": None, "params": []})
    assert spy.lines[-1] == tmp_path / "human"


# ------------------------------------------------------------------- metrics (§6)


def test_the_synthetic_summaries_are_the_registrys_metrics(tmp_path) -> None:
    from vge_analytics.synth import generate, measure_output

    generate(tmp_path / "synth", scale="tiny", seed=0, workers=1)
    measures = measure_output(tmp_path / "synth")
    runs = sorted(p for p in (tmp_path / "synth" / "runs").iterdir())
    replay.replay_runs(runs, tmp_path / "synth" / "bench", tmp_path / "out", progress=False)
    for row in va.metrics(tmp_path / "out").to_dicts():
        got = measures[row.pop("run_id")]
        row.pop("model")
        assert got.metrics == row
        assert got.sr == row["SR"] and got.gvpe == row["GVPE"]


def test_the_dashboard_reads_the_replays_mcap_path(pictured, monkeypatch) -> None:
    """An id that needs a hashed file name: the dashboard finds the replay's own file (it
    used to rebuild the name itself) instead of making the episode again."""
    long_id = "e1-" + "x" * 300
    tasks = pictured["bench"] / "tasks.jsonl"
    tasks.write_text(json.dumps(json.loads(tasks.read_text()) | {"episode_id": long_id}) + "\n")
    episodes = pictured["run"] / "episodes.jsonl"
    episodes.write_text(json.dumps(json.loads(episodes.read_text()) | {"episode_id": long_id}) + "\n")
    out = pictured["out"]
    replay.replay_runs([pictured["run"]], pictured["bench"], out, mcap=True, progress=False)
    path = replay.episode_mcap_path(out, "r", long_id).local
    assert path.is_file() and len(path.name.encode()) <= 205
    path.write_bytes(b"the replay's own file")
    monkeypatch.setattr(replay, "replay_episode", None)  # making it again would fail
    assert dash.episode_mcap(out, "r", long_id) == b"the replay's own file"
    shutil.rmtree(out)
