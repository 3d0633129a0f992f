"""Log steps written live carry token counts and latency (PROTOCOL §1.4, §10.2): the kernel
decodes such logs and gives the reference engine's tables; the fields fill the usage columns
(PROTOCOL §7.2) and change nothing else."""

from __future__ import annotations

import json

import msgspec

import replay
from replay.semantics import setup_episode

from .test_kernel import CASES, check_batch, episode, machine_of

USAGE = slice(replay.StepRow.__struct_fields__.index("prompt_tokens"), -1)
"""prompt_tokens, completion_tokens, latency_s, cost_usd: the columns the fields fill."""


def test_token_and_latency_fields_change_nothing() -> None:
    doc = json.loads((CASES / "kettle_c_parse_multigoal_chain.json").read_text())
    machine = machine_of(CASES.parent / doc["ssm"], doc["device_id"])
    task = msgspec.convert(doc["task"], replay.Task)
    plain = doc["episode"]["steps"]
    measured = [
        {**s, "prompt_tokens": 1000 + i, "completion_tokens": 40, "latency_seconds": 0.25 * i}
        for i, s in enumerate(plain)
    ]
    with_fields = episode(machine, task, measured, float(doc["lambda"]))
    assert with_fields.log.steps[1].prompt_tokens == 1001
    check_batch([with_fields, episode(machine, task, plain, float(doc["lambda"]))])
    setup = setup_episode(machine, task)
    rows = [
        replay.replay_episode(
            machine, task, e.log, lam=2.0, run_id="r", model="m", agent_kind="vlm", setup=setup
        ).step_tuples
        for e in (with_fields, episode(machine, task, plain, 2.0))
    ]
    assert [r[: USAGE.start] + r[USAGE.stop :] for r in rows[0]] == [
        r[: USAGE.start] + r[USAGE.stop :] for r in rows[1]
    ]
    # No prices in this run: the cost stays null.
    assert [r[USAGE] for r in rows[0][:2]] == [(1000, 40, 0.0, None), (1001, 40, 0.25, None)]
    assert all(r[USAGE] == (None,) * 4 for r in rows[1])
