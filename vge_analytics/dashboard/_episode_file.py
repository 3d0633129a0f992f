"""An episode's MCAP file for download: the replay's own, else made the same way."""


from __future__ import annotations

import io
import json
from pathlib import Path

import msgspec

import replay

from .._errors import UnknownRunError
from ..store import (
    bench_dir,
    resolve_input,
    run_entry,
)
from ..synth import image_source
from ._pictures import benchmark


def episode_mcap(out: str | Path, run_id: str, episode_id: str) -> bytes:
    """The episode's MCAP: OUT's file when the replay wrote one, else made now by replaying
    that one episode from the inputs the manifest records (same options, same bytes as
    `vge replay --mcap` would write)."""
    path = replay.episode_mcap_path(out, run_id, episode_id)
    if path.is_file():
        return path.read_bytes()
    entry = run_entry(out, run_id)
    inputs = entry["inputs"]
    bench_root = bench_dir(out, run_id)
    bench = benchmark(bench_root)
    run_dir = resolve_input(out, inputs["run_dir"])
    header = replay.read_run_header(run_dir)
    log = _find_episode_log(replay.episodes_file(run_dir), episode_id)
    task = bench.tasks[episode_id].task
    machine = bench.machine(task.device_id)
    lam = replay.episode_lambda(task, header.lam, (entry.get("options") or {}).get("lambda"))
    result = replay.replay_episode(
        machine,
        task,
        log,
        lam=lam,
        run_id=header.run_id,
        model=header.model,
        agent_kind=header.agent_kind,
        prices=replay.semantics.run_prices(header.meta),  # replayed already: the prices are valid
    )
    source = image_source(bench_root)
    buf = io.BytesIO()
    replay.write_episode_mcap(
        buf,
        machine,
        result,
        ssm_bytes=replay.attached_ssm(machine),
        image=lambda view: source(machine, view),
    )
    return buf.getvalue()


def _find_episode_log(path: Path, episode_id: str) -> replay.EpisodeLog:
    needle = json.dumps(episode_id).encode()
    for _, line in replay.io.iter_lines(path):
        if needle not in line:
            continue
        log = msgspec.json.decode(line, type=replay.EpisodeLog)
        if log.episode_id == episode_id:
            return log
    raise UnknownRunError(f"{path}: no episode {episode_id!r}")
