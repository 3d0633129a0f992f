"""`vge run --agent openai:MODEL` against a real OpenAI-compatible HTTP server on 127.0.0.1
with scripted replies: retries on 429, 500 and an unreadable body; a malformed answer scored
as the agent's error; infrastructure failures kept apart and played again by `--resume`.
The run directories replay with zero divergent steps and the metrics worked out below."""

from __future__ import annotations

import base64
import io
import json
from pathlib import Path

import msgspec
import pytest
from PIL import Image

import replay
import vge_analytics
from vge_analytics.cli import main
from vge_analytics.live import SYSTEM_PROMPT, FailureRecord

from .chat_server import NOT_JSON, answer, chat_server, error
from .conftest import MALFORMED, OPEN_LID, PUSH_POWER, WAIT


@pytest.fixture(autouse=True)
def _no_key(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("OPENAI_API_KEY", raising=False)


def _vge_run(bench: Path, out: Path, url: str, *extra: str) -> int:
    return main(
        [
            "run", str(bench), "--agent", "openai:scripted-vlm", "--out", str(out),
            "--base-url", url, "--retry-wait", "0.01", "--no-progress", *extra,
        ]
    )  # fmt: skip


def _replay(run: Path, bench: Path, out: Path) -> replay.Manifest:
    return replay.replay_runs([run], bench, out, progress=False)


def _lines(path: Path) -> list[dict]:
    return [json.loads(line) for line in path.read_text().splitlines()]


def test_a_scripted_server_run_replays_with_zero_divergence(
    kettle_bench: Path, tmp_path: Path
) -> None:
    script = [
        error(429, "slow down"),  # retried
        answer(MALFORMED),  # open-lid step 0: the agent's parse failure
        answer(OPEN_LID),  # open-lid step 1: LidOpen, success
        error(500, "overloaded"),  # retried
        NOT_JSON,  # retried
        answer(PUSH_POWER),  # boil step 0: Boiling
        answer(WAIT),  # boil step 1: BoilingComplete, success
    ]
    run = tmp_path / "run"
    with chat_server(script) as server:
        code = _vge_run(
            kettle_bench, run, server.url, "--prompt-price", "2.5", "--completion-price", "10"
        )
    assert code == 0
    assert len(server.requests) == 7 and not server.replies
    assert not (run / "failures.jsonl").exists()

    # What the model was sent: the rules, then the conversation so far, the picture last.
    first = server.requests[1]["body"]
    assert first["model"] == "scripted-vlm" and "temperature" not in first
    system, user = first["messages"]
    assert system == {"role": "system", "content": SYSTEM_PROMPT}
    text, picture = user["content"]
    assert "Request: Open the lid." in text["text"] and "Current view: right" in text["text"]
    url = picture["image_url"]["url"]
    assert url.startswith("data:image/png;base64,")
    with Image.open(io.BytesIO(base64.b64decode(url.split(",", 1)[1]))) as img:
        assert (img.format, img.size) == ("PNG", (768, 768))
    second = server.requests[2]["body"]["messages"]
    assert [m["role"] for m in second] == ["system", "user", "assistant", "user"]
    assert second[1]["content"] == user["content"]  # the past step, with its picture
    assert second[2]["content"] == MALFORMED
    assert "What happened: System Notification:" in second[3]["content"][0]["text"]
    assert server.requests[5]["body"]["messages"][1]["content"][0]["text"].startswith(
        "Request: Boil the water."  # a new episode starts a new conversation
    )

    # The log: the model's text and what the environment recorded, tokens and latency.
    episodes = _lines(run / "episodes.jsonl")
    assert [e["episode_id"] for e in episodes] == ["open-lid", "boil"]
    steps = [s for e in episodes for s in e["steps"]]
    assert [s["output"] for s in steps] == [MALFORMED, OPEN_LID, PUSH_POWER, WAIT]
    assert [s["feedback"] for s in steps] == [
        "invalid_action", "transition", "transition", "transition",
    ]  # fmt: skip
    assert [s["state"] for s in steps] == ["Standby", "LidOpen", "Boiling", "Standby"]
    assert all(s["prompt_tokens"] == 1000 and s["completion_tokens"] == 50 for s in steps)
    assert all(s["latency_seconds"] >= 0 and s["timestamp"] > 1.7e9 for s in steps)

    header = replay.read_run_header(run)
    assert (header.run_id, header.model, header.agent_kind, header.lam) == (
        "run", "scripted-vlm", "vlm", 5.0,
    )  # fmt: skip
    meta = header.meta
    assert meta["agent"] == "openai:scripted-vlm" and meta["history_length"] == "unlimited"
    assert (meta["episodes"], meta["infrastructure_failures"], meta["complete"]) == (2, 0, True)
    assert (meta["steps"], meta["prompt_tokens"], meta["completion_tokens"]) == (4, 4000, 200)
    # 4000 prompt tokens at 2.5 USD and 200 completion tokens at 10 USD per million.
    assert meta["cost_usd"] == pytest.approx(0.012)
    assert meta["latency_seconds"] >= 0

    out = tmp_path / "out"
    manifest = _replay(run, kettle_bench, out)
    counts = manifest.run("run").counts
    assert (counts.replayed, counts.steps, counts.diverged_steps) == (2, 4, 0)
    m = vge_analytics.metrics(out).row(0, named=True)
    # open-lid: success in 2 steps for C_opt 1 (SPL 0.5, not perfect); boil: 2 steps for
    # C_opt 2 (SPL 1, perfect). Interactions: the two pushes, both on targets. Operations:
    # the parse failure (not valid) and three transitions.
    assert (m["SR"], m["SSR"], m["SPL"], m["PSR"]) == (100.0, 100.0, 75.0, 50.0)
    assert (m["EIR"], m["TIR"], m["EER"], m["GVPE"]) == (100.0, 100.0, 75.0, 0.0)
    assert m["State-F1"] == 100.0
    errors = vge_analytics.error_distribution(out)
    assert errors.filter(errors["count"] > 0)["error_type"].to_list() == ["action_error"]


def test_a_request_that_keeps_failing_is_an_infrastructure_failure_and_resume_plays_it(
    kettle_bench: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = tmp_path / "run"
    script = [answer(OPEN_LID), answer(PUSH_POWER), error(500, "down"), error(503, "still down")]
    with chat_server(script) as server:
        assert _vge_run(kettle_bench, run, server.url, "--retries", "1") == 2
    assert [e["episode_id"] for e in _lines(run / "episodes.jsonl")] == ["open-lid"]
    (failure,) = [msgspec.convert(r, FailureRecord) for r in _lines(run / "failures.jsonl")]
    assert (failure.episode_id, failure.steps) == ("boil", 1)
    assert "2 attempt(s)" in failure.reason and "HTTP 503" in failure.reason
    meta = replay.read_run_header(run).meta
    assert (meta["episodes"], meta["infrastructure_failures"], meta["complete"]) == (1, 1, False)
    # Never scored: the replay knows only the finished episode.
    manifest = _replay(run, kettle_bench, tmp_path / "out1")
    assert manifest.run("run").counts.replayed == 1

    # Other settings than the run started with are refused, in one line.
    capsys.readouterr()
    with chat_server([]) as server:
        assert _vge_run(kettle_bench, run, server.url, "--resume", "--history", "2") == 1
    assert capsys.readouterr().err == (
        "error: --resume with other settings than the run was started with "
        "(history_length: 'unlimited' then, '2' now)\n"
    )

    with chat_server([answer(PUSH_POWER), answer(WAIT)]) as server:
        assert _vge_run(kettle_bench, run, server.url, "--retries", "1", "--resume") == 0
    assert len(server.requests) == 2  # open-lid was not played again
    assert [e["episode_id"] for e in _lines(run / "episodes.jsonl")] == ["open-lid", "boil"]
    assert not (run / "failures.jsonl").exists()
    meta = replay.read_run_header(run).meta
    assert (meta["episodes"], meta["infrastructure_failures"], meta["complete"]) == (2, 0, True)
    assert (meta["prompt_tokens"], meta["steps"]) == (3000, 3)
    counts = _replay(run, kettle_bench, tmp_path / "out2").run("run").counts
    assert (counts.replayed, counts.diverged_steps) == (2, 0)


def test_a_refused_model_stops_the_run_with_one_line(
    kettle_bench: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = tmp_path / "run"
    with chat_server([error(404, "The model does not exist")]) as server:
        assert _vge_run(kettle_bench, run, server.url) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: openai agent: no model 'scripted-vlm' at http://127.0.0.1:")
    assert "\n" not in err
    assert replay.read_run_header(run).meta["complete"] is False
