"""The harness of `vge run --agent openai:MODEL` fails fast and ends cleanly, against a real
HTTP server on 127.0.0.1 with scripted answers (PROTOCOL §10.3):

- before the first episode the server is checked: nothing listening, an unknown model or a
  refused key is one line, exit 1, and nothing is written;
- a 4xx other than 408, 409 and 429 is never retried and stops the run in one line (the
  episodes written stay; `--resume` continues);
- infrastructure failures in a row stop the run (exit 2) instead of failing every episode
  left; a finished episode starts the count again;
- a context-length refusal (OpenAI's, vLLM's, SGLang's, LiteLLM's) ends its episode as
  `context_exceeded`, scored as a failure and never an infrastructure failure;
- `--resume` may extend a run with more episodes.

Request counts say where retries happened and where none were due, and that a run which
fails before the first episode asked for none (`episode_requests`). No test bounds the
time a run takes (the machine may be busy), except where a wait of minutes is the fault:
there the bound is minutes too.
"""

from __future__ import annotations

import json
import socket
import time
from pathlib import Path

import pytest

import replay
import vge_analytics
from vge_analytics.cli import main
from vge_analytics.live._openai import ChatClient

from .chat_server import Scripted, answer, chat_server, error, model_list
from .conftest import OPEN_LID, PUSH_POWER, WAIT

MODEL = "scripted-vlm"


@pytest.fixture(autouse=True)
def _no_key(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("OPENAI_API_KEY", raising=False)


@pytest.fixture
def episode_requests(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """The requests of episodes (`ChatClient.complete`, not the check before the first
    episode), one entry each: a run that fails before the first episode makes none."""
    made: list[int] = []
    complete = ChatClient.complete

    def counted(self: ChatClient, *args: object, **kwargs: object) -> object:
        made.append(1)
        return complete(self, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(ChatClient, "complete", counted)
    return made


def _vge_run(bench: Path, out: Path, url: str, *extra: str) -> int:
    return main(
        [
            "run", str(bench), "--agent", f"openai:{MODEL}", "--out", str(out),
            "--base-url", url, "--retry-wait", "0.01", "--no-progress", *extra,
        ]
    )  # fmt: skip


def _timed_run(*args: object) -> tuple[int, float]:
    started = time.perf_counter()
    code = _vge_run(*args)  # type: ignore[arg-type]
    return code, time.perf_counter() - started


def _one_line(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err
    assert err.endswith("\n") and err.count("\n") == 1, err
    return err.rstrip("\n")


def _ids(path: Path) -> list[str]:
    return [json.loads(line)["episode_id"] for line in path.read_text().splitlines()]


def _body(message: str, code: str | None = None, type_: str | None = "test") -> dict:
    return {"error": {"message": message, "type": type_, "param": None, "code": code}}


def _refusal(status: int, body: dict, retry_after: str | None = None) -> Scripted:
    headers = (("Retry-After", retry_after),) if retry_after is not None else ()
    return Scripted(status, json.dumps(body).encode(), headers)


def _script(episode_ids: list[str]) -> list[Scripted]:
    """Answers that play `episode_ids` one after the other, each to success."""
    out = []
    for e in episode_ids:
        out += (
            [answer(OPEN_LID)] if e.startswith("open-lid") else [answer(PUSH_POWER), answer(WAIT)]
        )
    return out


def _free_port() -> int:
    """A port on 127.0.0.1 that nothing listens on (bound, then released)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _files(run: Path) -> dict[str, tuple[bytes, int]]:
    return {p.name: (p.read_bytes(), p.stat().st_mtime_ns) for p in sorted(run.iterdir())}


# ------------------------------------------------------------------ before the first episode


def test_nothing_listening_fails_at_once_and_writes_nothing(
    kettle_bench: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    episode_requests: list[int],
) -> None:
    url = f"http://127.0.0.1:{_free_port()}/v1"
    run = tmp_path / "run"
    # One attempt, no retries, no episode: with a retry wait of 5 minutes, any wait shows.
    code, seconds = _timed_run(kettle_bench, run, url, "--retry-wait", "300")
    assert code == 1
    assert _one_line(capsys) == (
        f"error: openai agent: cannot reach {url}: APIConnectionError: Connection error. "
        "([Errno 111] Connection refused)"
    )
    assert not run.exists()
    assert episode_requests == [] and seconds < 150, seconds

    # A run being resumed is not touched either.
    with chat_server([answer(OPEN_LID), error(500, "down")]) as server:
        assert _vge_run(kettle_bench, run, server.url, "--retries", "0") == 2
    before = _files(run)
    capsys.readouterr()
    episode_requests.clear()
    assert _vge_run(kettle_bench, run, url, "--resume") == 1
    assert "cannot reach" in _one_line(capsys)
    assert episode_requests == []
    assert _files(run) == before


def test_an_unknown_model_fails_before_the_first_episode(
    kettle_bench: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = tmp_path / "run"
    vllm_body = {
        "object": "error",
        "message": f"The model `{MODEL}` does not exist.",
        "type": "NotFoundError",
        "param": None,
        "code": 404,
    }
    refusal = _refusal(404, vllm_body)
    with chat_server([refusal], models=model_list("Qwen/Qwen2.5-VL-7B")) as server:
        assert _vge_run(kettle_bench, run, server.url) == 1
    assert _one_line(capsys) == (
        f"error: openai agent: no model '{MODEL}' at {server.url} (it serves "
        f"'Qwen/Qwen2.5-VL-7B'): HTTP 404: The model `{MODEL}` does not exist."
    )
    # The list, then one minimal request (a model may be served under a name not listed).
    assert server.listings == 1 and len(server.requests) == 1
    assert server.requests[0]["body"]["messages"] == [
        {"role": "user", "content": "Reply with the word OK."}
    ]
    assert not run.exists()


def test_a_server_without_a_list_of_models_is_asked_once(
    kettle_bench: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = tmp_path / "run"
    no_list = _refusal(404, {"detail": "Not Found"})
    with chat_server([error(404, "no such model")], models=no_list) as server:
        assert _vge_run(kettle_bench, run, server.url) == 1
    assert _one_line(capsys) == (
        f"error: openai agent: no model '{MODEL}' at {server.url}: HTTP 404: no such model"
    )
    assert (server.listings, len(server.requests)) == (1, 1) and not run.exists()

    # A model answered under a name the list does not hold (an alias) plays: the minimal
    # request passed, then the two episodes.
    with chat_server([answer("OK"), *_script(["open-lid", "boil"])], models=no_list) as server:
        assert _vge_run(kettle_bench, run, server.url) == 0
    assert (server.listings, len(server.requests)) == (1, 4)
    assert _ids(run / "episodes.jsonl") == ["open-lid", "boil"]


def test_a_refused_key_fails_before_the_first_episode(
    kettle_bench: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = tmp_path / "run"
    refused = _refusal(
        401,
        _body("Incorrect API key provided: sk-test.", "invalid_api_key", "invalid_request_error"),
    )
    with chat_server([], models=refused) as server:
        assert _vge_run(kettle_bench, run, server.url) == 1
    assert _one_line(capsys) == (
        "error: openai agent: the service refused the key: HTTP 401: Incorrect API key "
        "provided: sk-test."
    )
    assert (server.listings, len(server.requests)) == (1, 0)
    assert not run.exists()


# ------------------------------------------------------------------ during the run


@pytest.mark.parametrize(
    ("status", "message"),
    [
        (400, "Unsupported value: 'temperature' does not support 0.3 with this model."),
        (413, "Request Entity Too Large"),
        (422, "messages.1.content: Input should be a valid string"),
    ],
)
def test_a_refusal_for_good_is_not_retried_and_stops_the_run(
    kettle_bench: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    status: int,
    message: str,
) -> None:
    run = tmp_path / "run"
    script = [answer(OPEN_LID), _refusal(status, _body(message), retry_after="0")]
    with chat_server(script) as server:
        # The default retries (4): none is due (the second request is the last).
        assert _vge_run(kettle_bench, run, server.url, "--retry-wait", "2") == 1
    assert _one_line(capsys) == (
        f"error: openai agent: {server.url} refused the request, and would refuse every "
        f"request alike: HTTP {status}: {message}; 1 of 2 episodes written to {run}: the same "
        "command with --resume continues"
    )
    assert len(server.requests) == 2
    assert _ids(run / "episodes.jsonl") == ["open-lid"]
    assert not (run / "failures.jsonl").exists()  # not an infrastructure failure
    meta = replay.read_run_header(run).meta
    assert (meta["episodes"], meta["infrastructure_failures"], meta["complete"]) == (1, 0, False)

    with chat_server(_script(["boil"])) as server:
        assert _vge_run(kettle_bench, run, server.url, "--resume") == 0
    assert len(server.requests) == 2
    assert _ids(run / "episodes.jsonl") == ["open-lid", "boil"]
    assert replay.read_run_header(run).meta["complete"] is True


def test_408_409_and_429_are_retried(kettle_bench: Path, tmp_path: Path) -> None:
    script = [
        _refusal(408, _body("Request Timeout"), "0"),
        _refusal(409, _body("Conflict"), "0"),
        _refusal(429, _body("Rate limit reached"), "0"),
        *_script(["open-lid", "boil"]),
    ]
    with chat_server(script) as server:
        assert _vge_run(kettle_bench, tmp_path / "run", server.url, "--retries", "3") == 0
    assert len(server.requests) == 6 and not server.replies
    assert _ids(tmp_path / "run" / "episodes.jsonl") == ["open-lid", "boil"]


def test_ten_failures_in_a_row_stop_the_run_and_resume_completes_it(
    many_tasks: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    ids = list(replay.Benchmark.open(many_tasks).tasks)
    run = tmp_path / "run"
    # Two episodes play, then the server answers 500 to everything (the script has ended).
    with chat_server(_script(ids[:2])) as server:
        code = _vge_run(many_tasks, run, server.url, "--retries", "1")
    assert code == 2
    assert _one_line(capsys) == (
        f"stopped after 10 infrastructure failures in a row (last: no answer from {server.url} "
        "after 2 attempt(s); last: HTTP 500: script ended); 2 of 24 episodes written to "
        f"{run}: the same command with --resume continues"
    )
    # 3 answers, then 10 episodes of 2 attempts each (1 retry); the 12 others never asked.
    assert len(server.requests) == 3 + 10 * 2
    assert _ids(run / "episodes.jsonl") == ids[:2]
    assert _ids(run / "failures.jsonl") == ids[2:12]
    meta = replay.read_run_header(run).meta
    assert (meta["episodes"], meta["infrastructure_failures"], meta["complete"]) == (2, 10, False)

    with chat_server(_script(ids[2:])) as server:
        assert _vge_run(many_tasks, run, server.url, "--retries", "1", "--resume") == 0
    assert len(server.requests) == 11 * 1 + 11 * 2 and not server.replies
    assert _ids(run / "episodes.jsonl") == ids
    assert not (run / "failures.jsonl").exists()
    meta = replay.read_run_header(run).meta
    assert (meta["episodes"], meta["infrastructure_failures"], meta["complete"]) == (24, 0, True)
    counts = replay.replay_runs([run], many_tasks, tmp_path / "out", progress=False).run("run")
    assert (counts.counts.replayed, counts.counts.diverged_steps) == (24, 0)


def test_a_finished_episode_starts_the_count_again(
    many_tasks: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    down = error(500, "down")
    # open-lid-00 fails, boil-00 fails, open-lid-01 plays, boil-01 and open-lid-02 fail,
    # boil-02 plays: never 3 in a row.
    script = [down, down, answer(OPEN_LID), down, down, answer(PUSH_POWER), answer(WAIT)]
    common = ("--retries", "0", "--limit", "6")
    with chat_server(script) as server:
        code = _vge_run(
            many_tasks, tmp_path / "a", server.url, *common, "--max-consecutive-failures", "3"
        )
    assert code == 2 and len(server.requests) == 7
    assert _ids(tmp_path / "a" / "episodes.jsonl") == ["open-lid-01", "boil-02"]
    assert len(_ids(tmp_path / "a" / "failures.jsonl")) == 4
    assert "4 episode(s) ended on an infrastructure failure" in capsys.readouterr().out

    with chat_server(script) as server:
        code = _vge_run(
            many_tasks, tmp_path / "b", server.url, *common, "--max-consecutive-failures", "2"
        )
    assert code == 2 and len(server.requests) == 2
    assert _one_line(capsys).startswith("stopped after 2 infrastructure failures in a row")
    assert _ids(tmp_path / "b" / "failures.jsonl") == ["open-lid-00", "boil-00"]

    with chat_server([down] * 6) as server:  # 0: never stop
        code = _vge_run(
            many_tasks, tmp_path / "c", server.url, *common, "--max-consecutive-failures", "0"
        )
    assert code == 2 and len(server.requests) == 6
    assert len(_ids(tmp_path / "c" / "failures.jsonl")) == 6


def test_a_stopping_run_does_not_wait_for_retries(
    many_tasks: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Two episodes at once: one request is refused for good while the other waits the 5
    minutes its server asked before a retry; the wait is cut short and the run ends at once
    (in a second or two; the bound is far from both)."""
    busy = _refusal(500, _body("busy"), retry_after="300")
    refused = _refusal(400, _body("Unsupported parameter: 'max_tokens'"))
    run = tmp_path / "run"
    with chat_server([busy, refused]) as server:
        code, seconds = _timed_run(many_tasks, run, server.url, "--concurrency", "2")
    assert code == 1 and seconds < 150, seconds
    assert "refused the request" in _one_line(capsys)
    assert len(server.requests) == 2
    meta = replay.read_run_header(run).meta
    assert (meta["episodes"], meta["infrastructure_failures"]) == (0, 0)
    assert not (run / "failures.jsonl").exists()


# ------------------------------------------------------------------ the context window

CONTEXT_REFUSALS = {
    "openai": _body(
        "This model's maximum context length is 128000 tokens. However, your messages resulted "
        "in 131072 tokens. Please reduce the length of the messages.",
        "context_length_exceeded",
        "invalid_request_error",
    ),
    "vllm": {
        "object": "error",
        "message": "This model's maximum context length is 4096 tokens. However, your request "
        "has 5131 input tokens. Please reduce the length of the input messages.",
        "type": "BadRequestError",
        "param": None,
        "code": 400,
    },
    "vllm-decoder-prompt": _body(
        "The decoder prompt (length 8825) is longer than the maximum model length of 8192. "
        "Make sure that `max_model_len` is no smaller than the number of text tokens plus "
        "multimodal tokens.",
        "400",
        "BadRequestError",
    ),
    "sglang": {
        "object": "error",
        "message": "The input (5131 tokens) is longer than the model's context length "
        "(4096 tokens).",
        "type": "BadRequestError",
        "param": None,
        "code": 400,
    },
    "litellm": _body(
        "litellm.ContextWindowExceededError: litellm.BadRequestError: AnthropicException - "
        "prompt is too long: 209303 tokens > 200000 maximum\nReceived Model Group=scripted-vlm"
        "\nAvailable Model Group Fallbacks=None",
        "400",
        None,
    ),
}


@pytest.mark.parametrize("server_kind", list(CONTEXT_REFUSALS))
def test_a_context_refusal_ends_the_episode_as_context_exceeded(
    kettle_bench: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], server_kind: str
) -> None:
    run = tmp_path / "run"
    # open-lid succeeds; boil's first step is answered, its second request is too long.
    script = [answer(OPEN_LID), answer(PUSH_POWER), _refusal(400, CONTEXT_REFUSALS[server_kind])]
    with chat_server(script) as server:
        assert _vge_run(kettle_bench, run, server.url, "--retries", "4") == 0
    assert len(server.requests) == 3  # not retried
    summary = capsys.readouterr().out
    assert "1 ended by the model's context window (context_exceeded)" in summary
    lines = [json.loads(x) for x in (run / "episodes.jsonl").read_text().splitlines()]
    assert [(e["episode_id"], len(e["steps"]), e.get("ended")) for e in lines] == [
        ("open-lid", 1, None),
        ("boil", 1, "context_exceeded"),
    ]
    assert not (run / "failures.jsonl").exists()  # never an infrastructure failure
    meta = replay.read_run_header(run).meta
    assert (meta["episodes"], meta["infrastructure_failures"], meta["complete"]) == (2, 0, True)

    out = tmp_path / "out"
    manifest = replay.replay_runs([run], kettle_bench, out, progress=False)
    assert (manifest.run("run").counts.replayed, manifest.run("run").counts.diverged_steps) == (
        2,
        0,
    )
    episodes = vge_analytics.episodes(out).sort("episode_id")
    assert episodes["termination"].to_list() == ["context_exceeded", "success"]
    assert episodes["success"].to_list() == [False, True]
    m = vge_analytics.metrics(out).row(0, named=True)
    assert (m["SR"], m["SPL"]) == (50.0, 50.0)  # boil failed; open-lid in 1 step for C_opt 1


# ------------------------------------------------------------------ extending a run


def test_resume_extends_a_run_with_limit(
    kettle_bench: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = tmp_path / "run"
    with chat_server(_script(["open-lid"])) as server:
        assert _vge_run(kettle_bench, run, server.url, "--limit", "1") == 0
    meta = replay.read_run_header(run).meta
    assert (meta["episodes_selected"], meta["episodes"], meta["complete"]) == (1, 1, True)
    capsys.readouterr()

    with chat_server(_script(["boil"])) as server:
        assert _vge_run(kettle_bench, run, server.url, "--limit", "2", "--resume") == 0
    assert len(server.requests) == 2  # boil only
    assert (
        "2/2 episodes" in (out := capsys.readouterr().out) and "(extended from 1 selected)" in out
    )
    assert _ids(run / "episodes.jsonl") == ["open-lid", "boil"]
    meta = replay.read_run_header(run).meta
    assert (meta["episodes_selected"], meta["episodes"], meta["complete"]) == (2, 2, True)
    assert (meta["steps"], meta["prompt_tokens"]) == (3, 3000)

    # A run is extended, never cut down; other settings stay refused.
    before = _files(run)
    with chat_server([]) as server:
        assert _vge_run(kettle_bench, run, server.url, "--limit", "1", "--resume") == 1
        assert _one_line(capsys) == (
            f"error: {run / 'episodes.jsonl'} holds episode 'boil', which is not selected "
            "(--resume may add episodes to a run, not take them away)"
        )
        assert _vge_run(kettle_bench, run, server.url, "--resume", "--history", "1") == 1
        assert _one_line(capsys) == (
            "error: --resume with other settings than the run was started with "
            "(history_length: 'unlimited' then, '1' now)"
        )
    assert _files(run) == before


def test_resume_extends_a_run_with_episodes_in_selection_order(
    kettle_bench: Path, tmp_path: Path
) -> None:
    run = tmp_path / "run"
    with chat_server(_script(["boil"])) as server:
        assert _vge_run(kettle_bench, run, server.url, "--episodes", "boil") == 0
    with chat_server(_script(["open-lid"])) as server:
        assert _vge_run(kettle_bench, run, server.url, "--resume") == 0  # every task
    assert len(server.requests) == 1
    assert _ids(run / "episodes.jsonl") == ["open-lid", "boil"]  # tasks.jsonl's order
    assert replay.read_run_header(run).meta["episodes_selected"] == 2
