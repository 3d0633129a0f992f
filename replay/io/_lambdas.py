"""`replay_lambdas`: a batch of episode lines replayed at several lambdas (budget sweeps).

The batch function of `vge sweep`, run by the same executors as `replay_batch` (this
process, worker processes, Ray tasks). It returns episode rows, and for each episode
whether the logs support every lambda asked for: a log was produced under the budget of
its *recorded* lambda (the task's, else the run's, else 5); a larger lambda needs steps the
agent may never have been allowed to take. An episode supports a lambda L above its
recorded one when its replay at L does not end with `log_ended` (the log went far enough),
or when its replay at the recorded lambda already ended with `log_ended` (the log stopped
before its budget ran out, so a larger budget would not have produced more steps either).
"""

from __future__ import annotations

from dataclasses import dataclass

import msgspec
import numpy as np
import pyarrow as pa

from ..kernel import EpisodeInput, replay_kernel
from ..semantics import LOG_ENDED, episode_lambda
from ._load import decode_episode_line
from ._worker import worker_state


@dataclass(frozen=True)
class LambdaTask:
    """Lines of one run (`index`-th batch) to replay at every lambda of `lambdas` (sorted).
    Only the episodes in `episode_ids` count (those the replay output holds)."""

    run_id: str
    model: str
    agent_kind: str
    run_lambda: float | None
    bench: str
    index: int
    lines: tuple[tuple[int, bytes], ...]
    episode_ids: frozenset[str]
    lambdas: tuple[float, ...]


@dataclass
class LambdaBatch:
    """Episode rows of a batch, episode after episode and lambda after lambda within one;
    per episode its id and why its logs do not support a lambda (None when they do)."""

    index: int
    episodes: pa.Table
    episode_ids: list[str]
    refusals: list[str | None]


def replay_lambdas(task: LambdaTask) -> LambdaBatch:
    state = worker_state(task.bench)
    bench = state.bench
    inputs: list[EpisodeInput] = []
    recorded: list[float] = []
    seen: set[str] = set()
    for _, line in task.lines:
        try:
            log = decode_episode_line(line)
        except msgspec.DecodeError:
            continue  # quarantined by the replay: not in OUT either
        eid = log.episode_id
        entry = bench.tasks.get(eid)
        if eid not in task.episode_ids or eid in seen or entry is None:
            continue
        seen.add(eid)
        machine = bench.machine(entry.task.device_id)
        setup = state.setup(machine, entry.task)
        inputs.append(EpisodeInput(machine, entry.task, setup, log, 0.0))
        recorded.append(episode_lambda(entry.task, task.run_lambda))
    head = {"run_id": task.run_id, "model": task.model, "agent_kind": task.agent_kind}
    tables = [
        replay_kernel([e._replace(lam=lam) for e in inputs], **head).episodes
        for lam in task.lambdas
    ]
    refusals = _refusals(task, inputs, recorded, tables, head)
    n, k = len(inputs), len(task.lambdas)
    # episode-major, lambda-minor: row i*k + j is episode i at lambda j
    order = np.arange(n * k).reshape(n, k) % k * n + np.arange(n)[:, None]
    rows = pa.concat_tables(tables).take(pa.array(order.ravel())) if n else tables[0]
    return LambdaBatch(task.index, rows, [e.task.episode_id for e in inputs], refusals)


def _refusals(
    task: LambdaTask,
    inputs: list[EpisodeInput],
    recorded: list[float],
    tables: list[pa.Table],
    head: dict[str, str],
) -> list[str | None]:
    ended = [t.column("termination").to_pylist() for t in tables]
    suspects = [
        i
        for i in range(len(inputs))
        if any(
            lam > recorded[i] and ended[j][i] == LOG_ENDED for j, lam in enumerate(task.lambdas)
        )
    ]
    refusals: list[str | None] = [None] * len(inputs)
    if not suspects:
        return refusals
    at_recorded = replay_kernel(
        [inputs[i]._replace(lam=recorded[i]) for i in suspects], **head
    ).episodes.column("termination").to_pylist()
    for i, termination in zip(suspects, at_recorded, strict=True):
        if termination == LOG_ENDED:
            continue
        lam = next(
            lam
            for j, lam in enumerate(task.lambdas)
            if lam > recorded[i] and ended[j][i] == LOG_ENDED
        )
        refusals[i] = (
            f"run {task.run_id}: lambda {lam:g} is above the recorded lambda {recorded[i]:g} "
            f"and episode {inputs[i].task.episode_id} hit its budget there ({termination}); "
            f"its log holds no steps a larger budget would allow "
            f"(use lambdas <= {recorded[i]:g} for this run)"
        )
    return refusals
