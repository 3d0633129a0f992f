"""`vge synth`: generate a synthetic benchmark and simulated runs into a directory.

```
OUT/synth.json                      what was generated: scale, seed, versions, statistics
OUT/bench/ssm/<device_id>.json      one SSM per device
OUT/bench/ucsm/<Category>.json      the category templates used
OUT/bench/tasks.jsonl               the episodes
OUT/bench/images/<device>/<view>.png   only with images=True
OUT/runs/<run_id>/run.json          one directory per simulated run
OUT/runs/<run_id>/episodes.jsonl.gz
```

Work is split by device (instantiate, sample tasks, play every run's episodes); devices can
run in a process pool and results are written in device order, so the output is the same for
any number of workers. Everything is written under a temporary directory first and moved into
place at the end.
"""

from __future__ import annotations

import contextlib
import json
import math
import multiprocessing
import os
import shutil
import tempfile
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import msgspec

import replay
from replay.io import SSM_DIR, SSM_SUFFIX, UCSM_DIR, RunDirectory, ssm_path, tasks_path

from ._catalog import PAPER_DEVICE_COUNTS, UCSM_TEMPLATES, available_categories, load_catalog
from ._instantiate import dashboard_probability, dump_ssm, instantiate_device
from ._profiles import device_difficulty
from ._rng import rng_for
from ._runs import LAMBDA, RunSpec, agent_rng, choose_runs, episode_line, in_run, run_specs
from ._step_player import play_episode
from ._tasks import sample_tasks

SYNTH_VERSION = 1
"""Bumped whenever the same seed and scale would produce different files."""
MAX_AGENT_SEEDS = 100
MAX_DEVICE_SPREAD = 5.0
"""Bounds of `--seeds` and `--device-spread` (5 logits moves a 50% chance to 1% or 99%)."""
PAPER_SINGLE = 4948
PAPER_MULTI = 10005
_TINY_CATEGORIES = ("ElectricKettle", "Microwave", "Lamp", "WashingMachine")


class SynthError(Exception):
    """The output directory cannot be used."""


@dataclass(frozen=True, slots=True)
class Scale:
    """How much to generate."""

    name: str
    devices_per_category: int | None
    """None: the paper's per-category device counts."""
    single_per_device: int
    multi_per_device: int
    human_fraction: float
    history_fraction: float
    max_categories: int | None = None


SCALES: dict[str, Scale] = {
    "tiny": Scale("tiny", 2, 1, 2, 1.0, 1.0, max_categories=4),
    "sample": Scale("sample", 2, 2, 4, 0.5, 1.0),
    "full": Scale("full", None, 0, 0, 0.01, 0.1),
}


@dataclass(frozen=True, slots=True)
class DeviceJob:
    category: str
    device_id: str
    n_single: int
    n_multi: int


@dataclass(slots=True)
class DeviceResult:
    device_id: str
    category: str
    ssm_text: str
    task_lines: list[bytes]
    run_lines: dict[str, list[bytes]]
    stats: dict[str, int]


@dataclass(slots=True)
class Summary:
    """What a generation produced (also written to `synth.json`)."""

    scale: str
    seed: int
    categories: list[str]
    statistics: dict[str, int] = field(default_factory=dict)
    runs: dict[str, int] = field(default_factory=dict)
    options: dict[str, object] = field(default_factory=dict)
    """The options that change the runs (`agent_seeds`, `device_spread`, `runs`), only
    those not at their default (so a default output stays as it was)."""

    def to_json(self) -> dict:
        return {
            "generator": "vge synth",
            "synth_version": SYNTH_VERSION,
            "scale": self.scale,
            "seed": self.seed,
            **self.options,
            "categories": self.categories,
            "statistics": self.statistics,
            "runs": self.runs,
        }


def scale_categories(scale: Scale) -> tuple[str, ...]:
    cats = available_categories()
    if scale.max_categories is None:
        return cats
    preferred = [c for c in _TINY_CATEGORIES if c in cats]
    rest = [c for c in cats if c not in preferred]
    return tuple(sorted((preferred + rest)[: scale.max_categories]))


def plan_devices(scale: Scale, seed: int) -> list[DeviceJob]:
    """Devices in output order, with how many single- and multi-turn tasks each gets."""
    cats = scale_categories(scale)
    ids: list[tuple[str, str]] = []
    for cat in cats:
        n = scale.devices_per_category or PAPER_DEVICE_COUNTS.get(cat, 30)
        ids.extend((cat, f"{cat}_{i:03d}") for i in range(n))
    if scale.devices_per_category is not None:
        return [DeviceJob(c, d, scale.single_per_device, scale.multi_per_device) for c, d in ids]
    # Full scale: the paper's totals, spread evenly; remainders go to a seeded choice of devices.
    n = len(ids)
    total_single = round(PAPER_SINGLE * n / 968)
    total_multi = round(PAPER_MULTI * n / 968)
    order = sorted(range(n), key=lambda i: rng_for(seed, "quota", ids[i][1]).random())
    extra_single = set(order[: total_single % n])
    extra_multi = set(order[-(total_multi % n) :]) if total_multi % n else set()
    return [
        DeviceJob(
            c,
            d,
            total_single // n + (i in extra_single),
            total_multi // n + (i in extra_multi),
        )
        for i, (c, d) in enumerate(ids)
    ]


@dataclass(frozen=True, slots=True)
class _Context:
    seed: int
    dashboard_p: float
    runs: tuple[RunSpec, ...]
    device_spread: float = 0.0


def build_device(job: DeviceJob, ctx: _Context) -> DeviceResult:
    """Everything one device contributes: SSM, tasks, and every run's episodes on them."""
    device = instantiate_device(job.category, job.device_id, ctx.seed, dashboard_p=ctx.dashboard_p)
    text = dump_ssm(device.ssm)
    ssm = msgspec.json.decode(text.encode("utf-8"), type=replay.StateMachine)
    machine = replay.compile_machine(
        ssm, device_id=job.device_id, source=f"{SSM_DIR}/{job.device_id}{SSM_SUFFIX}"
    )
    tasks = sample_tasks(
        machine, job.category, job.n_single, job.n_multi, rng_for(ctx.seed, "tasks", job.device_id)
    )
    catalog = load_catalog(job.category)
    run_lines: dict[str, list[bytes]] = {}
    for spec in ctx.runs:
        difficulty = device_difficulty(
            ctx.seed, job.device_id, spec.profile.name, ctx.device_spread
        )
        profile = spec.profile.on_device(difficulty)
        lines = []
        for task in tasks:
            if not in_run(spec, ctx.seed, task.episode_id):
                continue
            rng = agent_rng(ctx.seed, spec.base, task.episode_id, spec.agent_seed)
            steps = play_episode(machine, catalog, profile, task, rng, LAMBDA)
            lines.append(episode_line(task.episode_id, steps, profile, ctx.seed, spec.run_id))
        run_lines[spec.run_id] = lines
    task_lines = [
        json.dumps(t.to_json(), ensure_ascii=False, separators=(",", ":")).encode("utf-8") + b"\n"
        for t in tasks
    ]
    return DeviceResult(
        job.device_id,
        job.category,
        text,
        task_lines,
        run_lines,
        _device_stats(device.ssm, machine, tasks),
    )


def _device_stats(ssm: dict, machine: replay.Machine, tasks) -> dict[str, int]:
    components: set[str] = set()
    boxes: set[tuple[str, str]] = set()
    transitions = 0
    for sdef in ssm["states"].values():
        for comp, trans in sdef["on"].items():
            transitions += len(trans)
            for t in trans:
                if "bbox" in t:
                    components.add(comp)
                    boxes.update((comp, b["view"]) for b in t["bbox"])
    return {
        "devices": 1,
        "views": len(machine.views),
        "dashboards": int(machine.has_dashboard),
        "unique_components": len(components),
        "annotated_bboxes": len(boxes),
        "states": len(ssm["states"]),
        "transitions": transitions,
        "episodes": len(tasks),
        "single_turn": sum(1 for t in tasks if len(t.goals) == 1),
        "multi_turn": sum(1 for t in tasks if len(t.goals) > 1),
        "goals": sum(len(t.goals) for t in tasks),
        "c_opt_total": sum(sum(t.c_opt) for t in tasks),
    }


def _build_star(args: tuple[DeviceJob, _Context]) -> DeviceResult:
    return build_device(*args)


def _results(jobs: list[DeviceJob], ctx: _Context, workers: int) -> Iterator[DeviceResult]:
    if workers <= 1 or len(jobs) <= 1:
        for job in jobs:
            yield build_device(job, ctx)
        return
    # Forked where that is safe (no other thread here: the CLI), else spawned: a fork of a
    # process running other threads (a test process's, a notebook's) copies their locks as
    # they are, and its children died under Python 3.13 (replay.io.start_method).
    context = multiprocessing.get_context(replay.io.start_method(fork=True))
    with ProcessPoolExecutor(max_workers=workers, mp_context=context) as pool:
        yield from pool.map(_build_star, [(job, ctx) for job in jobs], chunksize=2)


def _chosen_runs(
    sc: Scale, agent_seeds: int, device_spread: float, only_runs: Sequence[str] | None
) -> tuple[tuple[RunSpec, ...], dict[str, object]]:
    """(the runs to play, the options synth.json records: those not at their default)."""
    if not math.isfinite(device_spread) or not 0.0 <= device_spread <= MAX_DEVICE_SPREAD:
        raise SynthError(
            f"--device-spread must be between 0 and {MAX_DEVICE_SPREAD:g}, not {device_spread:g}"
        )
    if agent_seeds > MAX_AGENT_SEEDS:
        raise SynthError(f"--seeds must be at most {MAX_AGENT_SEEDS}, not {agent_seeds}")
    specs = run_specs(human_fraction=sc.human_fraction, history_fraction=sc.history_fraction)
    try:
        runs = choose_runs(specs, only_runs, agent_seeds)
    except ValueError as exc:
        raise SynthError(str(exc)) from None
    options: dict[str, object] = {}
    if agent_seeds != 1:
        options["agent_seeds"] = agent_seeds
    if device_spread:
        options["device_spread"] = float(device_spread)
    if only_runs is not None:
        options["only_runs"] = [s.run_id for s in runs if s.agent_seed == 0]
    return runs, options


def generate(
    out: Path,
    *,
    scale: str = "sample",
    seed: int = 0,
    workers: int | None = None,
    images: bool = False,
    progress: Callable[[int, int], None] | None = None,
    agent_seeds: int = 1,
    device_spread: float = 0.0,
    only_runs: Sequence[str] | None = None,
) -> Summary:
    """Write a synthetic benchmark and its simulated runs into `out` (replacing an earlier
    synthetic output there).

    `agent_seeds`: each run also played with seeds 1..N-1 (runs `<run_id>-seed<k>`, the
    same episodes, other random choices; run.json's `meta.seed` says k). `device_spread`:
    devices differ in difficulty by that many logits (a standard deviation), shared by every
    profile for the most part and partly each profile's own (`Profile.on_device`); 0 keeps
    every device as hard as its logic makes it. `only_runs`: these simulated runs only.
    The defaults give the output of earlier versions, byte for byte."""
    if scale not in SCALES:
        raise SynthError(f"unknown scale {scale!r} (choose from {', '.join(SCALES)})")
    sc = SCALES[scale]
    out = Path(out)
    _check_target(out)
    jobs = plan_devices(sc, seed)
    if not jobs:
        raise SynthError("no device categories available under vge_analytics/synth/data")
    runs, options = _chosen_runs(sc, agent_seeds, device_spread, only_runs)
    ctx = _Context(seed, dashboard_probability(), runs, float(device_spread))
    if workers is None:
        workers = os.cpu_count() or 1
    categories = sorted({j.category for j in jobs})
    summary = Summary(scale, seed, categories, options=options)

    out.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=".synth-", dir=out))
    try:
        bench = tmp / BENCH_DIR
        (bench / SSM_DIR).mkdir(parents=True)
        (bench / UCSM_DIR).mkdir()
        for cat in categories:
            name = f"{cat}{SSM_SUFFIX}"
            shutil.copyfile(UCSM_TEMPLATES / name, bench / UCSM_DIR / name)
        stats: dict[str, int] = {}
        with contextlib.ExitStack() as stack:
            writers = {}
            for spec in runs:
                run_dir = RunDirectory(tmp / RUNS_DIR / spec.run_id)
                writers[spec.run_id] = stack.enter_context(run_dir.stream(compress=True))
                run_dir.write_header(spec.header(seed, scale, ctx.device_spread))
            tasks_fh = stack.enter_context(open(tasks_path(bench), "wb"))
            for k, res in enumerate(_results(jobs, ctx, workers), start=1):
                ssm_path(bench, res.device_id).write_text(res.ssm_text, encoding="utf-8")
                tasks_fh.writelines(res.task_lines)
                for run_id, lines in res.run_lines.items():
                    writers[run_id].writelines(lines)
                    summary.runs[run_id] = summary.runs.get(run_id, 0) + len(lines)
                for key, value in res.stats.items():
                    stats[key] = stats.get(key, 0) + value
                if progress is not None:
                    progress(k, len(jobs))
        summary.statistics = stats
        (tmp / SUMMARY).write_text(
            json.dumps(summary.to_json(), indent=2, sort_keys=False) + "\n", encoding="utf-8"
        )
        if images:
            from ._prerender import prerender_images

            prerender_images(bench, workers=workers)
        _replace(out, tmp)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
    return summary


BENCH_DIR = "bench"
"""`OUT/bench`: the benchmark (PROTOCOL §1.1)."""
RUNS_DIR = "runs"
"""`OUT/runs/<run_id>`: one run directory per simulated run (PROTOCOL §1.4)."""
SUMMARY = "synth.json"
"""`OUT/synth.json`: what was generated."""
_OURS = (BENCH_DIR, RUNS_DIR, SUMMARY)


def _check_target(out: Path) -> None:
    if not out.exists():
        return
    if not out.is_dir():
        raise SynthError(f"{out}: not a directory")
    present = [name for name in (BENCH_DIR, RUNS_DIR) if (out / name).exists()]
    if present and not (out / SUMMARY).exists():
        raise SynthError(
            f"{out}: holds {', '.join(present)} not written by `vge synth` (no {SUMMARY}); "
            "choose another --out"
        )


def _replace(out: Path, tmp: Path) -> None:
    for name in _OURS:
        old = out / name
        if old.is_dir():
            shutil.rmtree(old)
        elif old.exists():
            old.unlink()
    for name in _OURS:
        src = tmp / name
        if src.exists():
            os.replace(src, out / name)
