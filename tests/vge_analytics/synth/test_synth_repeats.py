"""`vge synth --seeds`, `--device-spread` and `--runs`: repetitions of a run on the same
episodes with other choices, devices of unequal difficulty, a choice of runs; the defaults
change no byte (the bundled sample's test holds that for the whole tree)."""

from __future__ import annotations

import gzip
import json
from pathlib import Path

import pytest

from vge_analytics.cli import main
from vge_analytics.synth import SynthError, generate
from vge_analytics.synth._profiles import PROFILE_BY_NAME, device_difficulty


def _episodes(run: Path) -> list[dict]:
    return [json.loads(line) for line in gzip.open(run / "episodes.jsonl.gz")]


def test_repetitions_play_the_same_episodes_with_other_choices(synth_tiny, tmp_path):
    out = tmp_path / "seeds"
    generate(out, scale="tiny", seed=0, workers=1, agent_seeds=3, only_runs=["sim-vlm-f"])
    runs = sorted(p.name for p in (out / "runs").iterdir())
    assert runs == ["sim-vlm-f", "sim-vlm-f-seed1", "sim-vlm-f-seed2"]
    # repetition 0 is the run as the default output has it, byte for byte
    for name in ("run.json", "episodes.jsonl.gz"):
        ours = (out / "runs" / "sim-vlm-f" / name).read_bytes()
        assert ours == (synth_tiny / "runs" / "sim-vlm-f" / name).read_bytes()
    base = _episodes(out / "runs" / "sim-vlm-f")
    for k in (1, 2):
        other = _episodes(out / "runs" / f"sim-vlm-f-seed{k}")
        assert [e["episode_id"] for e in other] == [e["episode_id"] for e in base]
        assert [e["steps"] for e in other] != [e["steps"] for e in base]
        header = json.loads((out / "runs" / f"sim-vlm-f-seed{k}" / "run.json").read_text())
        assert header["meta"]["seed"] == k and header["model"] == "sim-vlm-f"
    assert (out / "bench" / "tasks.jsonl").read_bytes() == (
        synth_tiny / "bench" / "tasks.jsonl"
    ).read_bytes()
    summary = json.loads((out / "synth.json").read_text())
    assert summary["agent_seeds"] == 3 and summary["only_runs"] == ["sim-vlm-f"]
    assert "agent_seeds" not in json.loads((synth_tiny / "synth.json").read_text())


def test_device_spread_moves_the_runs_not_the_benchmark(synth_tiny, tmp_path):
    out = tmp_path / "spread"
    generate(out, scale="tiny", seed=0, workers=1, device_spread=1.5, only_runs=["sim-vlm-d"])
    for name in ("tasks.jsonl", "ssm"):
        a, b = out / "bench" / name, synth_tiny / "bench" / name
        files = sorted(a.rglob("*")) if a.is_dir() else [a]
        for f in files:
            assert f.read_bytes() == (b / f.relative_to(a) if a.is_dir() else b).read_bytes()
    run = out / "runs" / "sim-vlm-d"
    assert json.loads((run / "run.json").read_text())["meta"]["device_spread"] == 1.5
    assert _episodes(run) != _episodes(synth_tiny / "runs" / "sim-vlm-d")


def test_difficulty_is_shared_by_a_profiles_runs_and_mostly_by_all():
    assert device_difficulty(0, "Lamp_000", "sim-vlm-f", 0.0) == 0.0
    one = device_difficulty(0, "Lamp_000", "sim-vlm-f", 1.0)
    assert one == device_difficulty(0, "Lamp_000", "sim-vlm-f", 1.0)
    assert device_difficulty(0, "Lamp_000", "sim-vlm-f", 2.0) == pytest.approx(2 * one)
    assert device_difficulty(0, "Lamp_000", "sim-vlm-a", 1.0) != one
    # across many devices, two profiles' difficulties correlate by 1 - OWN_SHARE = 0.75
    f = [device_difficulty(0, f"d{i}", "sim-vlm-f", 1.0) for i in range(4000)]
    a = [device_difficulty(0, f"d{i}", "sim-vlm-a", 1.0) for i in range(4000)]
    mean_f, mean_a = sum(f) / len(f), sum(a) / len(a)
    cov = sum((x - mean_f) * (y - mean_a) for x, y in zip(f, a, strict=True)) / len(f)
    var_f = sum((x - mean_f) ** 2 for x in f) / len(f)
    var_a = sum((y - mean_a) ** 2 for y in a) / len(a)
    assert cov / (var_f * var_a) ** 0.5 == pytest.approx(0.75, abs=0.03)
    profile = PROFILE_BY_NAME["sim-human"]
    assert profile.on_device(0.0) is profile
    harder = profile.on_device(1.0)
    assert harder.component_knowledge < profile.component_knowledge and harder.sigma > profile.sigma
    assert harder.axo_mistake == profile.axo_mistake == 0.0  # a chance of 0 stays


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"agent_seeds": 0}, "--seeds must be 1 or more"),
        ({"agent_seeds": 101}, "--seeds must be at most 100"),
        ({"device_spread": -1.0}, "--device-spread must be between 0 and 5"),
        ({"device_spread": float("nan")}, "--device-spread must be between 0 and 5"),
        ({"only_runs": ["sim-robot"]}, "unknown simulated run 'sim-robot'"),
    ],
)
def test_bad_options_are_refused(tmp_path, options, message):
    with pytest.raises(SynthError, match=message):
        generate(tmp_path / "x", scale="tiny", workers=1, **options)


def test_cli_flags(tmp_path, capsys):
    out = tmp_path / "cli"
    assert main(["synth", "--out", str(out), "--scale", "tiny", "--workers", "1", "--seeds", "2",
                 "--runs", "sim-human"]) == 0  # fmt: skip
    assert sorted(p.name for p in (out / "runs").iterdir()) == ["sim-human", "sim-human-seed1"]
    assert main(["synth", "--out", str(out), "--device-spread", "9"]) == 1
    assert "--device-spread must be between 0 and 5" in capsys.readouterr().err
