"""An episode line read for the kernel (`decode_episode_line`): a `LogLine` where the
kernel's decoder takes it, msgspec's `EpisodeLog` where it does not, msgspec's errors for a
line to quarantine; and msgspec's log again for the reference replay (`episode_log`)."""

from __future__ import annotations

from pathlib import Path

import msgspec
import pytest

import replay
from replay.io import episode_decoder, episodes_file, iter_lines
from replay.io._decode import decode
from replay.io._load import decode_episode_line, episode_log
from replay.kernel import LogLine

LOGS = Path(__file__).resolve().parents[3] / "logs"


def test_a_line_either_way_gives_msgspec_s_log() -> None:
    raw = (
        b'{"episode_id":"e1","steps":[{"output":"Thinking: t.\\nAction: Timed_wait()",'
        b'"view":"front","timestamp":"2026-01-02T03:04:05Z","prompt_tokens":12},{}],'
        b'"ended":"context_exceeded"}'
    )
    log = decode_episode_line(raw)
    assert type(log) in (LogLine, replay.EpisodeLog)
    assert (log.episode_id, log.ended, log.continuation) == ("e1", "context_exceeded", None)
    assert episode_log(log) == episode_decoder.decode(raw)
    assert episode_log(log).steps[0].prompt_tokens == 12


def test_structured_actions_stay_msgspec_s() -> None:
    raw = b'{"episode_id":"e2","steps":[{"action":{"type":"Press","coord":[1,2]}}]}'
    log = decode_episode_line(raw)
    assert type(log) is replay.EpisodeLog
    assert episode_log(log) is log and log == episode_decoder.decode(raw)


@pytest.mark.parametrize(
    "raw",
    [b'{"episode_id":5,"steps":[]}', b'{"steps":[]}', b'{"episode_id":"e",', b"[" * 300],
)
def test_bad_lines_raise_msgspec_s_errors(raw: bytes) -> None:
    with pytest.raises(msgspec.DecodeError) as got:
        decode_episode_line(raw)
    with pytest.raises(msgspec.DecodeError) as want:
        decode(episode_decoder, raw)
    assert str(got.value) == str(want.value)


def test_every_line_of_the_sample() -> None:
    n = 0
    for run in sorted((LOGS / "runs").iterdir()):
        for _, raw in iter_lines(episodes_file(run)):
            assert episode_log(decode_episode_line(raw)) == episode_decoder.decode(raw)
            n += 1
    assert n == 2662
