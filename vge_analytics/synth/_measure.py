"""Replay simulated runs with the engine and summarise them: the numbers used to tune the
profiles, to check them in tests and to report them in docs/SYNTHETIC.md.

This is a small self-contained summary (SR, SSR, SPL, EIR, TIR, GVPE, error mix, the replay
health counters); the platform's full metrics live in the analytics package.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import replay


@dataclass(slots=True)
class RunMeasures:
    """Aggregates of one replayed run."""

    run_id: str
    model: str
    episodes: int = 0
    successes: int = 0
    goals: int = 0
    goals_completed: int = 0
    spl_sum: float = 0.0
    interactions: int = 0
    hits: int = 0
    target_hits: int = 0
    switches: int = 0
    steps: int = 0
    errors: Counter = field(default_factory=Counter)
    terminations: Counter = field(default_factory=Counter)
    truncated_steps: int = 0
    diverged_steps: int = 0
    ssr_sum: float = 0.0

    @property
    def sr(self) -> float:
        return 100.0 * self.successes / self.episodes if self.episodes else 0.0

    @property
    def ssr(self) -> float:
        return 100.0 * self.ssr_sum / self.episodes if self.episodes else 0.0

    @property
    def spl(self) -> float:
        return 100.0 * self.spl_sum / self.episodes if self.episodes else 0.0

    @property
    def eir(self) -> float:
        return 100.0 * self.hits / self.interactions if self.interactions else 0.0

    @property
    def tir(self) -> float:
        return 100.0 * self.target_hits / self.interactions if self.interactions else 0.0

    @property
    def gvpe(self) -> float:
        return self.switches / self.goals_completed if self.goals_completed else 0.0

    def error_groups(self) -> dict[str, float]:
        total = sum(self.errors.values())
        groups: Counter = Counter()
        for etype, n in self.errors.items():
            groups[replay.ERROR_GROUPS[etype]] += n
        return {g: 100.0 * n / total for g, n in sorted(groups.items())} if total else {}

    def error_shares(self) -> dict[str, float]:
        total = sum(self.errors.values())
        return {e: 100.0 * self.errors[e] / total for e in replay.ERROR_TYPES} if total else {}


def measure_run(bench: replay.Benchmark, run_dir: Path, lam: float | None = None) -> RunMeasures:
    """Replay every episode of a run directory against the benchmark."""
    header = replay.read_run_header(run_dir)
    use_lam = lam if lam is not None else (header.lam or replay.DEFAULT_LAMBDA)
    out = RunMeasures(header.run_id, header.model)
    for _, line in replay.iter_lines(replay.episodes_file(run_dir)):
        log = _decode(line)
        entry = bench.tasks[log.episode_id]
        machine = bench.machine(entry.task.device_id)
        res = replay.replay_episode(
            machine,
            entry.task,
            log,
            lam=use_lam,
            run_id=header.run_id,
            model=header.model,
            agent_kind=header.agent_kind,
        )
        add_episode(out, res)
    return out


def add_episode(out: RunMeasures, res: replay.EpisodeResult) -> None:
    ep = res.episode
    out.episodes += 1
    out.successes += int(ep.success)
    out.goals += ep.n_goals
    out.goals_completed += ep.goals_completed
    out.ssr_sum += ep.goals_completed / ep.n_goals
    out.spl_sum += ep.spl
    out.switches += ep.n_switches
    out.terminations[ep.termination] += 1
    out.truncated_steps += ep.truncated_steps
    out.diverged_steps += ep.diverged_steps
    for row in res.steps:
        if row.truncated:
            continue
        out.steps += 1
        if row.is_interaction:
            out.interactions += 1
            out.hits += int(bool(row.hit_component))
            out.target_hits += int(bool(row.hit_target))
        if row.error_type:
            out.errors[row.error_type] += 1


def _decode(line: bytes) -> replay.EpisodeLog:
    import msgspec

    return msgspec.json.decode(line, type=replay.EpisodeLog)


def measure_output(out_dir: Path) -> dict[str, RunMeasures]:
    """Every run under `out_dir/runs`, replayed against `out_dir/bench`, by run id."""
    bench = replay.Benchmark.open(Path(out_dir) / "bench")
    result = {}
    for run_dir in sorted(p for p in (Path(out_dir) / "runs").iterdir() if p.is_dir()):
        m = measure_run(bench, run_dir)
        result[m.run_id] = m
    return result
