"""Cost and completeness end to end (PROTOCOL §7.2, §7.3, §7.5, §10.2): `vge run` against a
real OpenAI-compatible HTTP server on 127.0.0.1, with prices; the replay prices every step,
and its columns add up to run.json's totals. A run cut short by server errors is replayed
like any other, and `vge metrics`, `compare` and `rescore` say it is incomplete."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import replay
import vge_analytics as va
from vge_analytics.cli import main

from .chat_server import answer, chat_server, error
from .conftest import MALFORMED, OPEN_LID, PUSH_POWER, WAIT
from .test_openai_run import _no_key, _vge_run  # noqa: F401 (_no_key: an autouse fixture)

PRICES = ("--prompt-price", "2.5", "--completion-price", "10")


@pytest.fixture
def two_runs(kettle_bench: Path, tmp_path: Path) -> Path:
    """`priced`: four answered steps; `short`: open-lid answered, boil refused twice by the
    server (one retry), an infrastructure failure. Both replayed into one OUT."""
    priced, short = tmp_path / "priced", tmp_path / "short"
    script = [
        answer(MALFORMED, 1200, 30),  # open-lid: ($1200 x 2.5 + 30 x 10) / 10^6 = $0.0033
        answer(OPEN_LID, 1500, 45),  # (3750 + 450) / 10^6 = $0.0042
        answer(PUSH_POWER, 900, 60),  # boil: (2250 + 600) / 10^6 = $0.00285
        answer(WAIT, 1100, 20),  # (2750 + 200) / 10^6 = $0.00295
    ]
    with chat_server(script) as server:
        assert _vge_run(kettle_bench, priced, server.url, *PRICES) == 0
    with chat_server(
        [answer(OPEN_LID, 1000, 40), error(500, "down"), error(500, "down")]
    ) as server:
        assert _vge_run(kettle_bench, short, server.url, *PRICES, "--retries", "1") == 2
    out = tmp_path / "out"
    replay.replay_runs([priced, short], kettle_bench, out, progress=False)
    return out


def test_step_costs_add_up_to_run_json(two_runs: Path, tmp_path: Path) -> None:
    steps = va.sql(
        two_runs,
        "SELECT episode_id, step, prompt_tokens, completion_tokens, latency_s, cost_usd, origin "
        "FROM steps WHERE run_id = 'priced' ORDER BY episode_id DESC, step",
    ).to_dicts()
    assert [(s["episode_id"], s["step"]) for s in steps] == [
        ("open-lid", 0), ("open-lid", 1), ("boil", 0), ("boil", 1),
    ]  # fmt: skip
    assert [(s["prompt_tokens"], s["completion_tokens"]) for s in steps] == [
        (1200, 30), (1500, 45), (900, 60), (1100, 20),
    ]  # fmt: skip
    assert [s["cost_usd"] for s in steps] == pytest.approx([0.0033, 0.0042, 0.00285, 0.00295])
    assert all(s["latency_s"] >= 0 and s["origin"] == "agent" for s in steps)

    episodes = va.episodes(two_runs, where={"run_id": "priced"}).to_dicts()
    for e in episodes:
        mine = [s for s in steps if s["episode_id"] == e["episode_id"]]
        assert e["prompt_tokens"] == sum(s["prompt_tokens"] for s in mine)
        assert e["completion_tokens"] == sum(s["completion_tokens"] for s in mine)
        assert e["latency_s"] == sum(s["latency_s"] for s in mine)
        assert e["cost_usd"] == pytest.approx(sum(s["cost_usd"] for s in mine), abs=1e-15)

    # The run's sums are run.json's totals: tokens exactly, latency to its millisecond,
    # cost to its 10^-6 USD ((4700 x 2.5 + 155 x 10) / 10^6 = $0.0133).
    meta = replay.read_run_header(tmp_path / "priced").meta
    assert (meta["prompt_price_per_mtok"], meta["completion_price_per_mtok"]) == (2.5, 10.0)
    totals = va.sql(
        two_runs,
        "SELECT sum(prompt_tokens) AS p, sum(completion_tokens) AS c, sum(latency_s) AS l, "
        "sum(cost_usd) AS usd FROM episodes WHERE run_id = 'priced'",
    ).row(0, named=True)
    assert (totals["p"], totals["c"]) == (meta["prompt_tokens"], meta["completion_tokens"])
    assert (totals["p"], totals["c"]) == (4700, 155)
    assert totals["l"] == pytest.approx(meta["latency_seconds"], abs=5e-4 * 4)
    assert totals["usd"] == pytest.approx(meta["cost_usd"], abs=5e-7)
    assert meta["cost_usd"] == pytest.approx(0.0133)


def test_a_run_cut_short_is_flagged(
    two_runs: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    meta = replay.read_run_header(tmp_path / "short").meta
    assert (meta["complete"], meta["infrastructure_failures"]) == (False, 1)
    runs = {r["run_id"]: r for r in va.runs(two_runs).to_dicts()}
    assert (runs["short"]["complete"], runs["short"]["infrastructure_failures"]) == (False, 1)
    assert (runs["priced"]["complete"], runs["priced"]["infrastructure_failures"]) == (True, 0)
    warning = (
        "warning: run 'short' is incomplete (run.json: complete false): 1 episode(s) ended on "
        "an infrastructure failure and are not scored; its metrics cover the episodes written "
        "so far (vge run --resume completes it)\n"
    )

    capsys.readouterr()
    assert main(["metrics", str(two_runs), "--metrics", "SR,SSR"]) == 0
    printed = capsys.readouterr()
    assert printed.err == warning
    assert "short (incomplete)" in printed.out and "priced (incomplete)" not in printed.out

    assert main(["metrics", str(two_runs), "--metrics", "SR", "--format", "json"]) == 0
    printed = capsys.readouterr()
    assert printed.err == warning
    rows = json.loads(printed.out)
    assert list(rows[0]) == ["run_id", "model", "complete", "SR"]  # after the group columns
    assert [(r["run_id"], r["complete"], r["SR"]) for r in rows] == [
        ("priced", True, 100.0),
        ("short", False, 100.0),  # the one episode written succeeded
    ]

    # Only the runs a command reports on are named.
    assert main(["metrics", str(two_runs), "--where", "run_id=priced"]) == 0
    assert capsys.readouterr().err == ""

    assert main(["compare", str(two_runs), "priced", "short", "--format", "json"]) == 0
    printed = capsys.readouterr()
    assert printed.err == warning
    summary = json.loads(printed.out)["summary"][0]
    assert (summary["complete_a"], summary["complete_b"], summary["n_common"]) == (True, False, 1)


def test_rescore_marks_the_incomplete_run(
    two_runs: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = tmp_path / "metrics"
    folder.mkdir()
    (folder / "sr.sql").write_text(
        (Path(va.__file__).parent / "sql" / "sr.sql")
        .read_text()
        .replace("count(*) FILTER (WHERE success)", "count(*) FILTER (WHERE success AND L_act > 1)")
    )
    capsys.readouterr()
    assert main(["rescore", str(two_runs), "--metrics-dir", str(folder), "-f", "json"]) == 0
    printed = capsys.readouterr()
    assert printed.err.count("warning: run 'short' is incomplete") == 1
    rows = json.loads(printed.out)
    assert list(rows[0])[:4] == ["metric", "run_id", "complete", "before"]
    # priced: both episodes took 2 steps (SR stays 100); short: open-lid in 1 step (100 -> 0).
    assert [(r["run_id"], r["complete"], r["before"], r["after"]) for r in rows] == [
        ("priced", True, 100.0, 100.0),
        ("short", False, 100.0, 0.0),
    ]
    assert main(["rescore", str(two_runs), "--metrics-dir", str(folder)]) == 0
    assert "short (incomplete)" in capsys.readouterr().out
