"""The usage and continuation columns (PROTOCOL §7.2, §7.3): tokens, latency and cost per step
and their sums per episode, the steps' origin and the episodes' continuation fields. Worked by
hand on one episode, then the kernel against the reference on generated logs with prices."""

from __future__ import annotations

import json

import msgspec
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import replay
from replay.kernel import EpisodeInput, replay_kernel
from replay.semantics import EpisodeRow, GoalRow, Prices, StepRow, rows_to_table

from .test_context_exceeded import _case
from .test_kernel import _episodes, assert_same, episode

PRICES = Prices(2.5, 10.0)


def _reference(episodes: list[EpisodeInput], prices: Prices):
    results = [
        replay.replay_episode(
            e.machine, e.task, e.log, lam=e.lam, run_id="run", model="model",
            agent_kind="vlm", setup=e.setup, prices=prices,
        )
        for e in episodes
    ]  # fmt: skip
    return (
        rows_to_table([t for r in results for t in r.step_tuples], StepRow),
        rows_to_table([r.episode for r in results], EpisodeRow),
        rows_to_table([g for r in results for g in r.goals], GoalRow),
    )


def _check(episodes: list[EpisodeInput], prices: Prices) -> None:
    steps, eps, goals = _reference(episodes, prices)
    got = replay_kernel(episodes, run_id="run", model="model", agent_kind="vlm", prices=prices)
    assert_same(got.steps, steps, "steps")
    assert_same(got.episodes, eps, "episodes")
    assert_same(got.goals, goals, "goals")


def test_usage_and_origin_worked_by_hand() -> None:
    """Three steps at 2.5 USD per million prompt tokens and 10 per million completion tokens:
    (1000, 50) costs (2500 + 500) / 10^6 = 0.003; (1200, none) 3000 / 10^6 = 0.003; a step
    with no count costs nothing known (null). The episode: 2200 and 50 tokens, latency
    0.5 + 0.25, cost (5500 + 500) / 10^6 = 0.006. Its first step repeats the source, the
    second is the fix, the third the agent's."""
    machine, task, steps, lam = _case("kettle_c_parse_multigoal_chain")
    steps = [
        {**steps[0], "prompt_tokens": 1000, "completion_tokens": 50, "latency_seconds": 0.5},
        {**steps[1], "prompt_tokens": 1200, "latency_seconds": 0.25},
        steps[2],
    ]
    cont = {"prefix_steps": 1, "fixed": True, "continued": True, "source_success": False}
    log = msgspec.convert(
        {"episode_id": task.episode_id, "steps": steps, "continuation": cont}, replay.EpisodeLog
    )
    e = EpisodeInput(machine, task, replay.semantics.setup_episode(machine, task), log, float(lam))
    result = replay.replay_episode(
        machine, task, log, lam=e.lam, run_id="r", model="m", agent_kind="vlm", prices=PRICES
    )
    rows = result.steps
    assert [(r.prompt_tokens, r.completion_tokens, r.latency_s) for r in rows] == [
        (1000, 50, 0.5),
        (1200, None, 0.25),
        (None, None, None),
    ]
    assert [r.cost_usd for r in rows] == [0.003, 0.003, None]
    assert [r.origin for r in rows] == ["prefix", "fix", "agent"]
    ep = result.episode
    assert (ep.prompt_tokens, ep.completion_tokens, ep.latency_s, ep.cost_usd) == (
        2200, 50, 0.75, 0.006,
    )  # fmt: skip
    assert (ep.prefix_steps, ep.fixed, ep.continued, ep.source_success) == (1, True, True, False)
    _check([e], PRICES)

    # Without prices nothing costs; without a continuation every step is the agent's.
    plain = episode(machine, task, steps, float(lam))
    bare = replay.replay_episode(
        machine, task, plain.log, lam=e.lam, run_id="r", model="m", agent_kind="vlm"
    )
    assert [r.cost_usd for r in bare.steps] == [None] * 3 and bare.episode.cost_usd is None
    assert [r.origin for r in bare.steps] == ["agent"] * 3
    assert bare.episode.prompt_tokens == 2200 and bare.episode.prefix_steps is None
    _check([plain, e], Prices(None, 1.6))


def test_a_continuation_field_that_does_not_fit_its_log_is_refused() -> None:
    """More prefix steps than the log has, a fix with no step left for it, a copy (not
    continued) with a fix: the line is not an episode record (PROTOCOL §7.6 invalid_record)."""
    decoder = msgspec.json.Decoder(replay.EpisodeLog)
    step = {"action": {"type": "Timed_wait"}}
    for prefix, fixed, continued, n in (
        (3, False, True, 2),
        (2, True, True, 2),
        (1, True, False, 2),
    ):
        line = {
            "episode_id": "e",
            "steps": [step] * n,
            "continuation": {
                "prefix_steps": prefix, "fixed": fixed, "continued": continued,
                "source_success": False,
            },
        }  # fmt: skip
        try:
            decoder.decode(json.dumps(line))
        except msgspec.ValidationError as exc:
            assert "continuation" in str(exc)
        else:
            raise AssertionError(f"accepted {line['continuation']}")


_PRICE_CHOICES = st.sampled_from(
    [Prices(), Prices(2.5, 10.0), Prices(0.4, None), Prices(None, 1.6), Prices(0.1234567, 3.3)]
)


@st.composite
def _with_usage(draw) -> list[EpisodeInput]:
    """Generated episodes whose steps record tokens and latencies (or not), some of them
    continuations with a prefix and a fix that fit their log."""
    out = []
    for e in draw(_episodes()):
        steps = []
        for s in e.log.steps:
            fields = {}
            if draw(st.booleans()):
                fields["prompt_tokens"] = draw(st.integers(0, 1 << 40))
            if draw(st.booleans()):
                fields["completion_tokens"] = draw(st.integers(0, 5000))
            if draw(st.booleans()):
                fields["latency_seconds"] = draw(
                    st.floats(0, 1e4, allow_nan=False, allow_infinity=False)
                )
            steps.append(msgspec.structs.replace(s, **fields))
        continuation = None
        n = len(steps)
        if n and draw(st.booleans()):
            continued = draw(st.booleans())
            fixed = continued and draw(st.booleans())
            prefix = draw(st.integers(0, n - fixed)) if continued else n
            continuation = replay.Continuation(prefix, fixed, continued, draw(st.booleans()))
        log = msgspec.structs.replace(e.log, steps=steps, continuation=continuation)
        out.append(e._replace(log=log))
    return out


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_with_usage(), _PRICE_CHOICES)
def test_generated_usage_columns_match_the_reference(
    episodes: list[EpisodeInput], prices: Prices
) -> None:
    _check(episodes, prices)
