"""The generated benchmark: valid SSMs in the paper's format, plannable tasks that an oracle
solves at exactly C_opt, deterministic output, and the bundled sample reproducible."""

from __future__ import annotations

import filecmp
import json
import re
from pathlib import Path

import msgspec
import pytest

import replay
from vge_analytics.synth import available_categories, generate, load_catalog

ROOT = Path(__file__).resolve().parents[3]
LOGS = ROOT / "logs"

PAPER_KEYS = {"name", "initial_state", "states"}
EXTENSION_KEYS = {"device_id", "category", "views", "images", "dashboard"}


def _ssm_paths(out: Path) -> list[Path]:
    return sorted((out / "bench" / "ssm").glob("*.json"))


def _tasks(out: Path) -> list[replay.Task]:
    return [
        msgspec.json.decode(line, type=replay.Task)
        for _, line in replay.io.iter_lines(out / "bench" / "tasks.jsonl")
    ]


def test_every_ssm_validates_with_no_problem(synth_tiny):
    paths = _ssm_paths(synth_tiny)
    assert len(paths) == 8  # the tiny scale: 4 categories of 2 devices
    for path in paths:
        ssm = replay.io.decode_state_machine(path)
        assert replay.semantics.validate_machine(ssm, str(path)) == [], path.name
    assert replay.validate_benchmark(synth_tiny / "bench") == []


def test_ssm_json_is_paper_format_plus_extensions(synth_tiny):
    for path in _ssm_paths(synth_tiny):
        raw = json.loads(path.read_text(encoding="utf-8"))
        assert PAPER_KEYS <= set(raw) <= PAPER_KEYS | EXTENSION_KEYS, path.name
        assert raw["device_id"] == path.stem
        for sdef in raw["states"].values():
            assert set(sdef) <= {"description", "on", "is_error"}
            for comp, trans in sdef["on"].items():
                for t in trans:
                    if comp in ("immediate", "timed_wait"):
                        assert set(t) == {"next_state", "transition_description"}
                    else:
                        assert list(t) == [
                            "next_state",
                            "transition_description",
                            "bbox",
                            "atomic_action",
                            "parameter",
                        ]
                        for box in t["bbox"]:
                            assert set(box) == {"coordinate", "view"}
                            assert all(isinstance(v, int) for v in box["coordinate"])


def test_no_two_components_overlap_in_a_view(synth_tiny):
    for path in _ssm_paths(synth_tiny):
        machine = replay.load_machine(path)
        for view, items in machine.component_rects.items():
            rects = {}
            for comp, r in items:
                rects.setdefault(comp, []).append(r)
            names = sorted(rects)
            for i, a in enumerate(names):
                for b in names[i + 1 :]:
                    for ra in rects[a]:
                        for rb in rects[b]:
                            overlap = (
                                ra[0] < rb[2] and rb[0] < ra[2] and ra[1] < rb[3] and rb[1] < ra[3]
                            )
                            assert not overlap, f"{path.stem} {view}: {a} overlaps {b}"
            for region in machine.dashboard_regions.get(view, ()):
                for comp, r in items:
                    inside = (
                        r[0] < region[2]
                        and region[0] < r[2]
                        and r[1] < region[3]
                        and region[1] < r[3]
                    )
                    assert not inside, f"{path.stem} {view}: {comp} inside the dashboard region"


def test_image_sizes_like_the_real_data(synth_tiny):
    for path in _ssm_paths(synth_tiny):
        raw = json.loads(path.read_text(encoding="utf-8"))
        sizes = {}
        for sdef in raw["states"].values():
            for trans in sdef["on"].values():
                for t in trans:
                    for box in t.get("bbox", []):
                        size = tuple(box["coordinate"][4:])
                        assert sizes.setdefault(box["view"], size) == size, "one size per view"
        for view, (w, h) in sizes.items():
            if view != "dashboard":
                assert 700 <= w <= 1420 and 700 <= h <= 1420, (path.stem, view, w, h)


def _oracle_log(setup: replay.semantics.EpisodeSetup, episode_id: str) -> replay.EpisodeLog:
    steps = [
        replay.LogStep(output=f"Thinking: follow the plan.\nAction: {s.action.to_text()}")
        for s in setup.plan.steps
    ]
    return replay.EpisodeLog(episode_id=episode_id, steps=steps)


def test_oracle_reaches_every_goal_at_exactly_c_opt(synth_tiny):
    bench = replay.Benchmark.open(synth_tiny / "bench")
    tasks = _tasks(synth_tiny)
    assert len(tasks) == 24  # 8 devices, 1 single-goal and 2 multi-goal tasks each
    for task in tasks:
        machine = bench.machine(task.device_id)
        setup = replay.semantics.setup_episode(machine, task)
        assert list(setup.plan.c_opt) == list(task.c_opt), task.episode_id
        res = replay.replay_episode(
            machine,
            task,
            _oracle_log(setup, task.episode_id),
            lam=5.0,
            run_id="oracle",
            model="oracle",
            agent_kind="scripted",
        )
        assert res.episode.success, task.episode_id
        assert res.episode.L_act == res.episode.L_opt == sum(task.c_opt)
        assert res.episode.termination == "success"
        for goal in res.goals:
            assert goal.completed and goal.steps_used == goal.c_opt, (task.episode_id, goal)


def test_tasks_shape_and_instructions(synth_tiny):
    tasks = _tasks(synth_tiny)
    singles = [t for t in tasks if len(t.goals) == 1]
    multis = [t for t in tasks if len(t.goals) > 1]
    assert singles and multis
    assert all(2 <= len(t.goals) <= 4 for t in multis)
    for t in tasks:
        assert len(t.instructions) == len(t.goals)
        assert len(set(t.goals)) == len(t.goals), "no goal repeated"
        assert t.initial_view != "dashboard"


def _words(text: str) -> str:
    return " " + re.sub(r"[^a-z0-9]+", " ", text.lower()) + " "


def test_instructions_never_name_a_component(synth_tiny):
    bench = replay.Benchmark.open(synth_tiny / "bench")
    for task in _tasks(synth_tiny):
        machine = bench.machine(task.device_id)
        catalog = load_catalog(machine.category)
        names = {c.replace("_", " ") for c in catalog.components}
        for text in task.instructions:
            for name in names:
                assert f" {name} " not in _words(text), (task.episode_id, text, name)


def _same_tree(a: Path, b: Path) -> list[str]:
    """Relative paths that differ (missing on either side, or different bytes)."""
    diffs = []
    files_a = {p.relative_to(a) for p in a.rglob("*") if p.is_file()}
    files_b = {p.relative_to(b) for p in b.rglob("*") if p.is_file()}
    diffs.extend(str(p) for p in sorted(files_a ^ files_b))
    for rel in sorted(files_a & files_b):
        if not filecmp.cmp(a / rel, b / rel, shallow=False):
            diffs.append(str(rel))
    return diffs


def test_generation_is_deterministic_and_worker_independent(synth_tiny, tmp_path):
    again = tmp_path / "again"
    generate(again, scale="tiny", seed=0, workers=2)
    assert _same_tree(synth_tiny, again) == []
    other = tmp_path / "other"
    generate(other, scale="tiny", seed=1, workers=1)
    assert _same_tree(synth_tiny, other) != []


def test_bundled_sample_reproduces_byte_for_byte(tmp_path):
    """`vge synth --out logs --scale sample --seed 0` must give exactly the committed logs/."""
    assert (LOGS / "synth.json").exists(), "logs/ holds no synthetic sample"
    meta = json.loads((LOGS / "synth.json").read_text())
    assert meta["scale"] == "sample" and meta["seed"] == 0
    out = tmp_path / "sample"
    generate(out, scale="sample", seed=0, workers=2)
    assert _same_tree(out, LOGS) == []


def test_sample_covers_every_category():
    meta = json.loads((LOGS / "synth.json").read_text())
    assert meta["categories"] == list(available_categories())


@pytest.mark.parametrize("scale", ["tiny"])
def test_replaying_simulated_logs_matches_the_simulation(synth_tiny, scale):
    from vge_analytics.synth import measure_output

    measures = measure_output(synth_tiny)
    # The tiny scale: 4 categories of 2 devices, 1 single-goal and 2 multi-goal tasks each
    # = 24 episodes, all played by every run (human and history fractions 1.0): the six
    # profiles, the human-like run and two history-length variants of sim-vlm-f.
    assert sorted(measures) == [
        "sim-human",
        *(f"sim-vlm-{p}" for p in "abcdef"),
        "sim-vlm-f-hist0",
        "sim-vlm-f-hist3",
    ]
    for m in measures.values():
        assert m.episodes == 24
        assert m.truncated_steps == 0
        assert m.diverged_steps == 0
        assert "log_ended" not in m.terminations


def test_profiles_keep_the_papers_order_on_the_sample():
    """Replayed from the bundled sample: the simulated profiles rank like the paper's models
    (weakest first), the human-like profile above them, and no history hurts the strongest."""
    from vge_analytics.synth import PROFILES, measure_output

    measures = measure_output(LOGS)
    for m in measures.values():
        assert m.truncated_steps == 0 and m.diverged_steps == 0
        assert "log_ended" not in m.terminations
    order = [p.name for p in PROFILES]
    rates = [measures[name].sr for name in order]
    assert rates == sorted(rates), dict(zip(order, rates, strict=True))
    assert rates[0] < 5.0 and 40.0 < measures["sim-vlm-f"].sr < 70.0
    assert measures["sim-vlm-f-hist0"].sr < measures["sim-vlm-f"].sr


def test_run_headers_say_they_are_simulated():
    for run_dir in sorted((LOGS / "runs").iterdir()):
        header = replay.read_run_header(run_dir)
        meta = header.meta
        assert meta["simulated"] is True
        assert {"profile", "mimics", "history_length", "perturbation"} <= set(meta)
        assert meta["instruction_generator"]
        assert header.lam == 5.0
        if header.agent_kind == "human":
            first = next(replay.io.iter_lines(replay.episodes_file(run_dir)))[1]
            step = json.loads(first)["steps"][0]
            assert "action" in step and "output" not in step
