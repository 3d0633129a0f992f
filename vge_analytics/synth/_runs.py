"""Simulated runs: which runs a synthetic benchmark has, their headers (`run.json`), and the
episode lines (PROTOCOL §1.4) their agents write."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import orjson

from ._agent import AgentStep
from ._profiles import PROFILES, STRONGEST_VLM, Profile
from ._rng import derive_seed, rng_for
from ._step_player import think_seconds

LAMBDA = 5.0
EPOCH = 1767225600
"""2026-01-01T00:00:00Z: synthetic timestamps start in the four weeks after it."""
INSTRUCTION_GENERATOR = "catalog-phrases"


@dataclass(frozen=True, slots=True)
class RunSpec:
    """One simulated run: a profile, its history setting, the share of episodes it plays."""

    run_id: str
    profile: Profile
    fraction: float = 1.0
    """Share of the benchmark's episodes in this run (deterministic subset)."""
    agent_seed: int = 0
    """Which repetition of the run this is: 0 is the run itself, k >= 1 the same profile on
    the same episodes with other random choices (`vge synth --seeds`)."""
    family: str = ""
    """The run id of repetition 0 (empty: this run's own)."""

    @property
    def base(self) -> str:
        """The run id its repetitions share (their subset of episodes, their choices' seed)."""
        return self.family or self.run_id

    def header(self, seed: int, scale: str, device_spread: float = 0.0) -> dict:
        p = self.profile
        history = "unlimited" if p.history_length is None else str(p.history_length)
        extra: dict = {}
        if self.agent_seed:
            extra["seed"] = self.agent_seed
        if device_spread:
            extra["device_spread"] = device_spread
        return {
            "run_id": self.run_id,
            "model": p.name,
            "agent_kind": p.agent_kind,
            "lambda": LAMBDA,
            "meta": {
                "simulated": True,
                "profile": p.name,
                "mimics": p.mimics,
                "history_length": history,
                "perturbation": "none",
                "instruction_generator": INSTRUCTION_GENERATOR,
                "synth_seed": seed,
                "synth_scale": scale,
                **extra,
            },
        }


def run_specs(*, human_fraction: float, history_fraction: float) -> tuple[RunSpec, ...]:
    """Every profile on the whole benchmark (the human one on a subset, as in the paper), plus
    the strongest VLM profile again with history lengths 3 and 0 (the paper's history study)."""
    specs: list[RunSpec] = []
    for p in PROFILES:
        if p.agent_kind == "human":
            specs.append(RunSpec(p.name, p, human_fraction))
        else:
            specs.append(RunSpec(p.name, p))
    strongest = next(p for p in PROFILES if p.name == STRONGEST_VLM)
    for h in (3, 0):
        specs.append(
            RunSpec(f"{strongest.name}-hist{h}", strongest.with_history(h), history_fraction)
        )
    return tuple(specs)


def choose_runs(
    specs: Sequence[RunSpec], only: Sequence[str] | None, seeds: int
) -> tuple[RunSpec, ...]:
    """The runs `only` names (all when None), each with its repetitions 1..seeds-1 after it
    (`<run_id>-seed<k>`). Raises ValueError naming an unknown run."""
    if seeds < 1:
        raise ValueError(f"--seeds must be 1 or more, not {seeds}")
    known = [s.run_id for s in specs]
    for name in only or ():
        if name not in known:
            raise ValueError(f"unknown simulated run {name!r}; runs: {', '.join(known)}")
    chosen = [s for s in specs if only is None or s.run_id in only]
    return tuple(
        spec
        if k == 0
        else replace(spec, run_id=f"{spec.run_id}-seed{k}", agent_seed=k, family=spec.run_id)
        for spec in chosen
        for k in range(seeds)
    )


def in_run(spec: RunSpec, seed: int, episode_id: str) -> bool:
    """Whether an episode belongs to the run's deterministic subset (shared by its
    repetitions)."""
    if spec.fraction >= 1.0:
        return True
    return derive_seed(seed, "subset", spec.base, episode_id) < spec.fraction * 2.0**64


def agent_rng(seed: int, run_id: str, episode_id: str, agent_seed: int = 0):
    """The agent's choices on an episode; repetition k >= 1 of a run draws its own."""
    if agent_seed:
        return rng_for(seed, "agent", run_id, episode_id, agent_seed)
    return rng_for(seed, "agent", run_id, episode_id)


def episode_line(
    episode_id: str, steps: list[AgentStep], profile: Profile, seed: int, run_id: str
) -> bytes:
    """One line of `episodes.jsonl` with recorded view, feedback kind, state and time."""
    clock = rng_for(seed, "clock", run_id, episode_id)
    t = float(EPOCH + clock.randrange(28 * 86400))
    out = []
    for st in steps:
        t += think_seconds(profile, clock)
        item: dict = {}
        if st.output is not None:
            item["output"] = st.output
        else:
            item["action"] = st.record
        item["view"] = st.view
        item["feedback"] = st.outcome.kind
        item["state"] = st.state
        item["timestamp"] = round(t, 3)
        out.append(item)
    return orjson.dumps({"episode_id": episode_id, "steps": out}) + b"\n"
