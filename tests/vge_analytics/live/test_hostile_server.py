"""`vge run` against a model server that is broken or hostile (PROTOCOL §10.3), as a real
process under an address-space bound (`tests.bounded`), against a real HTTP server on
127.0.0.1 that makes its answers as it sends them (`chat_server.Streamed`):

- an answer of a gigabyte, with its length declared or not, as a 200 or as an error's body,
  and one of 50 MB: dropped at `--max-response-bytes` (4 MiB) while it is read, so the run's
  peak memory is that of a run with small answers, give or take a few MB;
- 50 MB answers under a cap raised past them: taken, until the episode's line would pass
  the replay's bound on a record (64 MiB): then the episode is an infrastructure failure,
  not a line the replay would quarantine;
- an answer trickled a byte at a time, in its body or its headers: cut off at `--timeout`,
  a deadline for the whole request;
- token counts out of the protocol's bounds (negative, 10^22, not whole numbers), a text
  that is not a string, JSON nested too deep, a compressed answer: unreadable answers.

Each is retried (`--retries 1`: two requests), then ends its episode as an infrastructure
failure whose reason names the server and the bound; the other episodes are played and the
run replays with nothing quarantined. The counts of requests and episodes are asserted,
never how long a run took.
"""

from __future__ import annotations

import gzip
import json
import sys
from pathlib import Path

import pytest

import replay
import vge_analytics as va
from tests.bounded import run_bounded
from vge_analytics.cli import main

from .chat_server import Scripted, Streamed, answer, chat_server, huge, trickle
from .conftest import OPEN_LID, PUSH_POWER, WAIT, write_kettle_bench

MODEL = "scripted-vlm"
MiB = 1 << 20
CAP = 4 * MiB
"""The default `--max-response-bytes`."""
GOOD = [answer(OPEN_LID), answer(PUSH_POWER), answer(WAIT)]
"""Answers that play both kettle episodes (open-lid, boil) to success."""


@pytest.fixture(autouse=True)
def _no_key(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("OPENAI_API_KEY", raising=False)


def _args(bench: Path, out: Path, url: str, *extra: str) -> list[str]:
    return [
        "run", str(bench), "--agent", f"openai:{MODEL}", "--out", str(out), "--base-url", url,
        "--retries", "1", "--retry-wait", "0.01", "--no-progress", *extra,
    ]  # fmt: skip


def _vge_run(bench: Path, out: Path, url: str, *extra: str) -> tuple[int, int, str]:
    """`vge run` as its own process: exit code, peak resident memory, stderr."""
    done = run_bounded(
        [sys.executable, "-m", "vge_analytics.cli", *_args(bench, out, url, *extra)],
        timeout=600,
    )
    return done.returncode, done.peak_memory, done.stderr


@pytest.fixture(scope="module")
def small_answers_peak(tmp_path_factory: pytest.TempPathFactory) -> int:
    """The peak memory of `vge run` playing both episodes with small answers."""
    tmp = tmp_path_factory.mktemp("small")
    bench = write_kettle_bench(tmp / "bench")
    with chat_server(list(GOOD)) as server:
        code, peak, err = _vge_run(bench, tmp / "run", server.url)
    assert code == 0 and len(server.requests) == 3, err
    return peak


def _failures(run: Path) -> list[dict]:
    return [json.loads(x) for x in (run / "failures.jsonl").read_text().splitlines()]


def _replays_whole(run: Path, bench: Path, out: Path, episodes: int) -> None:
    """The run replays: its episodes, nothing quarantined, no divergent step."""
    counts = replay.replay_runs([run], bench, out, progress=False).run(run.name).counts
    assert (counts.replayed, counts.quarantined, counts.diverged_steps) == (episodes, 0, 0)


@pytest.mark.parametrize(
    "reply",
    [
        pytest.param(huge(1 << 30), id="1GB-answer"),
        pytest.param(huge(1 << 30, status=500, declared=False), id="1GB-error-body-no-length"),
        pytest.param(huge(50 * MiB), id="50MB-answer"),
    ],
)
def test_a_huge_answer_is_dropped_while_it_is_read(
    kettle_bench: Path, tmp_path: Path, small_answers_peak: int, reply: Streamed
) -> None:
    run = tmp_path / "run"
    # open-lid gets the huge answer twice (retried once), then boil plays.
    with chat_server([reply, reply, answer(PUSH_POWER), answer(WAIT)]) as server:
        code, peak, err = _vge_run(kettle_bench, run, server.url)
    assert code == 2, err
    assert len(server.requests) == 4
    [failure] = _failures(run)
    assert failure == {
        "episode_id": "open-lid",
        "steps": 0,
        "reason": f"no answer from {server.url} after 2 attempt(s); last: an answer of more "
        f"than {CAP:,} bytes (--max-response-bytes)",
    }
    # 16.6 GB before the cap, for the gigabyte; now a few MB above a run of small answers.
    assert peak < small_answers_peak + 64 * MiB, (peak, small_answers_peak)
    assert (run / "episodes.jsonl").stat().st_size < 10_000
    meta = replay.read_run_header(run).meta
    assert (meta["episodes"], meta["infrastructure_failures"], meta["complete"]) == (1, 1, False)
    _replays_whole(run, kettle_bench, tmp_path / "out", 1)


def test_answers_past_the_record_bound_end_the_episode_not_the_replay(
    kettle_bench: Path, tmp_path: Path
) -> None:
    """With the cap raised past them, two answers of 50 MB (not actions: the episode goes
    on after the first) would make an episode's line of 100 MB, which the replay would
    quarantine whole: the second ends the episode as an infrastructure failure instead."""
    run = tmp_path / "run"
    big = huge(50 * MiB)
    with chat_server([big, big, answer(PUSH_POWER), answer(WAIT)]) as server:
        code, peak, err = _vge_run(
            kettle_bench, run, server.url, "--max-response-bytes", str(replay.MAX_RECORD_BYTES)
        )
    assert code == 2, err
    assert len(server.requests) == 4  # both answers taken, none retried
    [failure] = _failures(run)
    assert failure["episode_id"] == "open-lid" and failure["steps"] == 1
    assert failure["reason"] == (
        "the answers make the episode's line longer than 67,108,864 bytes, the most a record "
        "may be (PROTOCOL §1.5)"
    )
    assert peak < 1536 * MiB, peak
    _replays_whole(run, kettle_bench, tmp_path / "out", 1)


@pytest.mark.parametrize("where", ["body", "headers"])
def test_a_trickled_answer_is_cut_off_at_the_deadline(
    kettle_bench: Path, tmp_path: Path, where: str
) -> None:
    """A byte every 0.5 s: every read is answered within the timeout, the answer never
    ends (240 bytes: 2 minutes a request). The deadline of 2 s ends each of the two."""
    run = tmp_path / "run"
    slow = trickle(0.5, where)
    with chat_server([slow, slow, answer(PUSH_POWER), answer(WAIT)]) as server:
        code = main(_args(kettle_bench, run, server.url, "--timeout", "2"))
    assert code == 2
    assert len(server.requests) == 4
    [failure] = _failures(run)
    assert failure["reason"] == (
        f"no answer from {server.url} after 2 attempt(s); last: no whole answer within 2 s"
    )
    _replays_whole(run, kettle_bench, tmp_path / "out", 1)


def _usage(prompt: object, completion: object) -> Scripted:
    body = json.loads(answer(OPEN_LID).body)
    body["usage"] = {"prompt_tokens": prompt, "completion_tokens": completion}
    return Scripted(200, json.dumps(body).encode())


def _content(content: object) -> Scripted:
    body = json.loads(answer(OPEN_LID).body)
    body["choices"][0]["message"]["content"] = content
    return Scripted(200, json.dumps(body).encode())


UNREADABLE = {
    "negative-prompt-tokens": (
        _usage(-5, 50),
        "Expected `int` >= 0 - at `$.prompt_tokens`",
    ),
    "1e22-completion-tokens": (
        _usage(1000, 10**22),
        "Expected `int` <= 1099511627776 - at `$.completion_tokens`",
    ),
    "2^40+1-prompt-tokens": (
        _usage(2**40 + 1, 50),
        "Expected `int` <= 1099511627776 - at `$.prompt_tokens`",
    ),
    "fractional-tokens": (
        _usage(1000.5, 50),
        "Expected `int | null`, got `float` - at `$.prompt_tokens`",
    ),
    "text-not-a-string": (
        _content(["Push"]),
        "Expected `str | null`, got `array` - at `$.output`",
    ),
}


@pytest.mark.parametrize("case", list(UNREADABLE))
def test_an_answer_out_of_the_protocols_bounds_is_not_written(
    kettle_bench: Path, tmp_path: Path, case: str
) -> None:
    reply, said = UNREADABLE[case]
    run = tmp_path / "run"
    with chat_server([reply, reply, answer(PUSH_POWER), answer(WAIT)]) as server:
        assert main(_args(kettle_bench, run, server.url)) == 2
    assert len(server.requests) == 4
    [failure] = _failures(run)
    assert failure["episode_id"] == "open-lid"
    assert failure["reason"].startswith(
        f"no answer from {server.url} after 2 attempt(s); last: unreadable answer: an "
        "answer out of a step's bounds (PROTOCOL §1.4): "
    )
    assert failure["reason"].endswith(said)
    meta = replay.read_run_header(run).meta
    assert (meta["episodes"], meta["prompt_tokens"], meta["completion_tokens"]) == (1, 2000, 100)
    _replays_whole(run, kettle_bench, tmp_path / "out", 1)


def test_token_counts_at_the_bound_are_written(kettle_bench: Path, tmp_path: Path) -> None:
    run = tmp_path / "run"
    with chat_server([_usage(2**40, 0), answer(PUSH_POWER), answer(WAIT)]) as server:
        assert main(_args(kettle_bench, run, server.url)) == 0
    assert len(server.requests) == 3
    meta = replay.read_run_header(run).meta
    assert (meta["prompt_tokens"], meta["completion_tokens"]) == (2**40 + 2000, 100)
    _replays_whole(run, kettle_bench, tmp_path / "out", 2)


def test_answers_that_cannot_be_parsed_are_retried_then_failed(
    kettle_bench: Path, tmp_path: Path
) -> None:
    """JSON nested past the parser's depth, and a compressed answer nobody asked for."""
    deep = Scripted(200, b"[" * 200_000 + b"]" * 200_000)
    packed = gzip.compress(answer(OPEN_LID).body)
    compressed = Scripted(200, packed, (("Content-Encoding", "gzip"),))
    run = tmp_path / "run"
    with chat_server([deep, deep, compressed, compressed]) as server:
        assert main(_args(kettle_bench, run, server.url)) == 2
    assert len(server.requests) == 4
    reasons = [f["reason"].split("; last: ")[1] for f in _failures(run)]
    assert reasons[0].startswith("unreadable answer: RecursionError: ")
    assert reasons[1] == "a compressed answer (gzip), though none was asked for"


@pytest.mark.parametrize("price", ["-1", "nan", "inf", "1e300", "1000001"])
def test_a_price_past_its_bound_is_refused_before_the_server_is_asked(
    kettle_bench: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], price: str
) -> None:
    """A price is at most 10^6 USD per million tokens (PROTOCOL §1.4): 10^300 times 2^40 tokens would be a
    cost of infinity (written as null, shown as $inf)."""
    run = tmp_path / "run"
    with chat_server(list(GOOD)) as server:
        assert main(_args(kettle_bench, run, server.url, "--completion-price", price)) == 1
    assert len(server.requests) == 0 and not run.exists()
    [line] = capsys.readouterr().err.strip().splitlines()
    assert line.endswith(
        f"--completion-price: a price is a number of USD per million tokens from 0 to "
        f"1,000,000, not {float(price)!r}"
    )


def test_the_costliest_step_at_the_highest_price_is_a_number(
    kettle_bench: Path, tmp_path: Path
) -> None:
    """2^40 prompt tokens at 10^6 USD per million: (2^40 x 10^6) / 10^6 = 2^40 USD."""
    run = tmp_path / "run"
    with chat_server([_usage(2**40, 0), answer(PUSH_POWER), answer(WAIT)]) as server:
        assert main(_args(kettle_bench, run, server.url, "--prompt-price", "1e6")) == 0
    # open-lid's one step; boil's two of 1000 prompt tokens: 2 x 1000 x 10^6 / 10^6 USD.
    usd = 2**40 + 2000
    assert replay.read_run_header(run).meta["cost_usd"] == pytest.approx(usd, rel=1e-12)
    out = tmp_path / "out"
    _replays_whole(run, kettle_bench, out, 2)
    [row] = va.sql(out, "SELECT sum(cost_usd) AS usd FROM steps").to_dicts()
    assert row["usd"] == pytest.approx(usd, rel=1e-12)
