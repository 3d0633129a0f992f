"""`vge compare` (pair and --all), `vge power` and `vge passk` on the command line: every
format, the same output for the same seed, and bad input as one line."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from vge_analytics.cli import main


def run(capsys, *args: str) -> tuple[int, str, str]:
    code = main([*args])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_compare_says_what_it_resamples(capsys, clustered_out: Path) -> None:
    code, out, _ = run(
        capsys, "compare", str(clustered_out), "A", "B", "--metrics", "SR", "-f", "json"
    )
    assert code == 0
    doc = json.loads(out)
    summary, (sr,) = doc["summary"][0], doc["metrics"]
    assert (summary["cluster"], summary["n_clusters"], summary["correction"]) == (
        "device",
        3,
        "holm",
    )
    assert (sr["ci_low"], sr["ci_high"], sr["p_value"]) == (-50.0, 100.0, 0.75)
    assert sr["deff"] == pytest.approx(1.75, rel=1e-12)
    assert doc["mcnemar"][0]["p_cluster"] == pytest.approx(0.414216, abs=1e-6)
    _, again, _ = run(
        capsys, "compare", str(clustered_out), "A", "B", "--metrics", "SR", "-f", "json"
    )
    assert again == out  # same seed, same bytes
    code, out, _ = run(
        capsys, "compare", str(clustered_out), "A", "B", "--cluster", "episode",
        "--correction", "none", "-f", "json",
    )  # fmt: skip
    doc = json.loads(out)
    assert doc["summary"][0]["n_clusters"] == 6
    assert doc["metrics"][0]["deff"] == pytest.approx(1.0, rel=1e-12)


@pytest.mark.parametrize("fmt", ["table", "json", "csv", "markdown"])
def test_every_new_report_in_every_format(capsys, clustered_out: Path, fmt: str) -> None:
    for args in (
        ("compare", str(clustered_out), "--all", "--resamples", "50"),
        ("compare", str(clustered_out), "--all", "--by", "model", "--metric", "SSR"),
        ("power", str(clustered_out), "A", "B"),
        ("power", str(clustered_out), "--rate", "0.5", "--icc", "0.1"),
        ("passk", str(clustered_out), "--per-episode", "--resamples", "50"),
    ):
        code, out, err = run(capsys, *args, "--format", fmt)
        assert code == 0, (args, err)
        assert out.strip()
    code, out, _ = run(capsys, "compare", str(clustered_out), "--all", "-f", "json")
    doc = json.loads(out)
    assert set(doc) == {"summary", "ranking", "pairs"}
    assert [r["letters"] for r in doc["ranking"]] == ["a"] * 4


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("compare", "{out}"), "compare needs RUN_A and RUN_B, or --all"),
        (("compare", "{out}", "A", "B", "--all"), "--all compares every run"),
        (("compare", "{out}", "A", "B", "--cluster", "run"), "unknown cluster 'run'"),
        (("compare", "{out}", "A", "B", "--correction", "bonf"), "unknown correction 'bonf'"),
        (("compare", "{out}", "A", "B", "--seed", "-1"), "the seed must be 0 or more"),
        (("compare", "{out}", "--all", "--by", "nope"), "--by 'nope' is not a column"),
        (("power", "{out}", "A", "B", "--delta", "0"), "--delta must be a positive difference"),
        (("power", "{out}", "A"), "power takes two runs"),
        (("power", "{out}"), "power needs RUN_A RUN_B, or --rate"),
        (("power", "{out}", "A", "B", "--rate", "0.5"), "--rate and --icc plan without runs"),
        (("passk", "{out}", "--k", "0"), "k must be between 1 and 1000, not 0"),
        (("passk", "{out}", "--k", "1000000000"), "k must be between 1 and 1000"),
        (("compare", "{out}", "A", "B", "--resamples", "10000000000"), "resamples must be between"),
        (("compare", "{out}", "--all", "--resamples", "0"), "resamples must be between 1 and"),
        (("passk", "{out}", "--group-by", "nope"), "--group-by 'nope' is not a column"),
    ],
)
def test_bad_input_is_one_line(capsys, clustered_out: Path, args, message: str) -> None:
    code, out, err = run(capsys, *[a.format(out=clustered_out) for a in args])
    assert code == 1 and out == ""
    assert message in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err


def test_no_common_episode_is_one_line(capsys, hand_out: Path) -> None:
    code, _, err = run(capsys, "compare", str(hand_out), "kettle-vlm", "oven-human")
    assert code == 1 and "no episode in common" in err
    code, _, err = run(capsys, "power", str(hand_out), "kettle-vlm", "oven-human")
    assert code == 1 and "no episode in common" in err
