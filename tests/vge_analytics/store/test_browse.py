"""Row-level API for the dashboard: runs, facets, episodes, goals, steps."""

from __future__ import annotations

from pathlib import Path

import polars as pl
import pytest

import vge_analytics as va


def test_runs_and_facets(hand_out: Path) -> None:
    runs = va.runs(hand_out)
    assert runs["run_id"].to_list() == ["kettle-vlm", "oven-human"]
    assert runs["n_episodes"].to_list() == [7, 5]
    assert runs["n_success"].to_list() == [4, 5]
    assert {"model", "agent_kind", "lambda", "meta_history", "meta_perturbation"} <= set(
        runs.columns
    )
    assert va.facets(hand_out) == {
        "meta_history": ["3", "full"],
        "meta_perturbation": ["blur", "none"],
    }


def test_episodes_goals_steps(hand_out: Path) -> None:
    eps = va.episodes(hand_out, where={"meta_perturbation": "blur"})
    assert eps["episode_id"].to_list() == [f"hw_dash_{c}" for c in "abcde"]
    two = va.episodes(
        hand_out, where={"n_goals": [2], "run_id": "kettle-vlm"}, columns=["episode_id"]
    )
    assert two.columns == ["episode_id"]
    assert two["episode_id"].to_list() == [
        "hw_kettle_a", "hw_kettle_d", "hw_kettle_e", "hw_kettle_f",
    ]  # fmt: skip
    goals = va.goals(hand_out, where={"episode_id": "hw_kettle_c"})
    assert goals["goal_index"].to_list() == [0, 1, 2]
    steps = va.episode_steps(hand_out, "kettle-vlm", "hw_kettle_b")
    assert steps["step"].to_list() == list(range(8))
    assert steps["truncated"].to_list() == [False] * 6 + [True] * 2
    scored = va.steps(hand_out, where={"truncated": False, "category": "Oven"})
    assert scored.height == 32


def test_browse_errors(hand_out: Path) -> None:
    with pytest.raises(va.UnknownRunError):
        va.episode_steps(hand_out, "nope", "x")
    with pytest.raises(va.UnknownColumnError):
        va.episodes(hand_out, columns=["nope"])
    with pytest.raises(va.UnknownColumnError):
        va.steps_with_error(hand_out, "nope")


def test_out_dir_errors(tmp_path: Path) -> None:
    with pytest.raises(va.OutputDirError, match="not found"):
        va.metrics(tmp_path / "missing")
    with pytest.raises(va.OutputDirError, match="not a replay output"):
        va.metrics(tmp_path)


def test_empty_out_dir(tmp_path: Path, hand_out: Path) -> None:
    for table in ("steps", "episodes", "goals", "runs"):
        (tmp_path / table).mkdir()
    df = va.metrics(tmp_path)
    assert df.height == 0 and df.columns == ["run_id", "model", *va.METRIC_NAMES]
    errors = va.error_distribution(tmp_path)
    assert errors.height == 0 and errors.schema == va.error_distribution(hand_out).schema
    # No run: no row, and the columns (and types) of an OUT with runs, less its facets.
    runs, filled = va.runs(tmp_path), va.runs(hand_out)
    assert runs.height == 0
    assert runs.schema == filled.drop(pl.selectors.starts_with("meta_")).schema
