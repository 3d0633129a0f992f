"""Benchmark of `vge replay` (not a test): throughput, bare JSON decoding, peak RSS, MCAP.

Usage (on the full synthetic benchmark):

    vge synth --out /tmp/vge-full --scale full
    .venv/bin/python benchmarks/bench_replay.py /tmp/vge-full [--workers 1,2]
        [--engines columnar,scalar] [--repeat N] [--stages] [--profile]

DATA is a directory with `bench/` and `runs/*` (what `vge synth` writes). Measures:
- bare decoding: the episode files read and decoded line by line with msgspec (typed, into
  the same `EpisodeLog` records the replay uses), and with orjson (untyped), in-process;
- end to end (logs -> Parquet, `replay_runs(..., force=True)`) with each engine (the
  columnar default, and the scalar reference via `VGE_REPLAY_ENGINE=scalar`) and worker
  count, each in a fresh subprocess, with its peak RSS (main process, largest worker);
  `--repeat N` runs each N times and keeps the one with the least CPU time (the machine
  may be shared: CPU time is the steadier measure);
- MCAP: milliseconds per episode of `write_episode_mcap` on a sample of episodes;
- with `--stages`: CPU time per stage of a one-worker replay of all runs (columnar engine),
  in a fresh subprocess, from timers around the stage functions;
- with `--profile`: a cProfile of a one-worker replay of the largest run, time split by
  module (runner code vs core engine vs libraries).
Prints a Markdown report (the numbers in docs/PERFORMANCE.md come from it).
"""

from __future__ import annotations

import argparse
import cProfile
import gzip
import io
import json
import os
import pstats
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import orjson

import replay
from replay.io._load import episode_decoder

CORES = os.cpu_count() or 1
RUNNER_MODULES = (
    "_runner",
    "_reading",
    "_runjob",
    "_batch",
    "_writer",
    "_outdir",
    "_manifest",
    "_quarantine",
    "_mcap",
)


def _episode_files(data: Path) -> list[Path]:
    return sorted(replay.episodes_file(d) for d in (data / "runs").iterdir() if d.is_dir())


def _read(path: Path) -> bytes:
    raw = path.read_bytes()
    return gzip.decompress(raw) if path.suffix == ".gz" else raw


def bare_decoding(files: list[Path]) -> dict[str, float]:
    """Seconds to read + decode every line: msgspec typed, orjson untyped; step count."""
    steps = 0
    t0 = time.perf_counter()
    c0 = time.process_time()
    for path in files:
        for line in _read(path).splitlines():
            if line.strip():
                steps += len(episode_decoder.decode(line).steps)
    t_msgspec = time.perf_counter() - t0
    c_msgspec = time.process_time() - c0
    t0 = time.perf_counter()
    for path in files:
        for line in _read(path).splitlines():
            if line.strip():
                orjson.loads(line)
    t_orjson = time.perf_counter() - t0
    t0 = time.perf_counter()
    for path in files:
        _read(path)
    t_read = time.perf_counter() - t0
    return {
        "steps": steps,
        "msgspec_s": t_msgspec,
        "msgspec_cpu_s": c_msgspec,
        "orjson_s": t_orjson,
        "read_s": t_read,
    }


_CHILD = """
import json, resource, sys, time
import replay
runs, bench, out, workers = json.loads(sys.argv[1])
t0 = time.perf_counter()
m = replay.replay_runs(runs, bench, out, workers=workers, force=True, progress=False)
wall = time.perf_counter() - t0
me = resource.getrusage(resource.RUSAGE_SELF)
kids = resource.getrusage(resource.RUSAGE_CHILDREN)
print(json.dumps({
    "wall_s": wall,
    "main_cpu_s": me.ru_utime + me.ru_stime,
    "workers_cpu_s": kids.ru_utime + kids.ru_stime,
    "steps": m.content.totals.steps,
    "episodes": m.content.totals.replayed,
    "quarantined": m.content.totals.quarantined,
    "main_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    "worker_rss_mb": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024,
}))
"""


def end_to_end(data: Path, out: Path, workers: int, engine: str) -> dict[str, float]:
    runs = [str(d) for d in sorted((data / "runs").iterdir()) if d.is_dir()]
    arg = json.dumps([runs, str(data / "bench"), str(out), workers])
    env = {**os.environ, "VGE_REPLAY_ENGINE": engine, "POLARS_MAX_THREADS": "1"}
    done = subprocess.run(
        [sys.executable, "-c", _CHILD, arg], check=True, capture_output=True, text=True, env=env
    )
    result = json.loads(done.stdout.strip().splitlines()[-1])
    result["load"] = _load()
    return result


def mcap_ms_per_episode(data: Path, n: int) -> dict[str, float]:
    """Replay `n` episodes of the largest run; time `write_episode_mcap` alone, with the
    view images (the CLI's image source) fetched beforehand."""
    from replay.io._batch import as_image_tuple
    from vge_analytics.commands.replay import image_source

    bench = replay.Benchmark.open(data / "bench")
    images = image_source(data / "bench")
    files = _episode_files(data)
    largest = max(files, key=lambda p: p.stat().st_size)
    total = image_total = 0.0
    count = with_images = 0
    for line in _read(largest).splitlines()[:n]:
        log = episode_decoder.decode(line)
        task = bench.tasks[log.episode_id].task
        machine = bench.machine(task.device_id)
        result = replay.replay_episode(
            machine, task, log, lam=5.0, run_id="r", model="m", agent_kind="vlm"
        )
        ssm = Path(machine.source).read_bytes()
        t0 = time.perf_counter()
        views = {r.view_before for r in result.steps if r.view_before} | {
            result.episode.initial_view
        }
        cache = {v: as_image_tuple(images(machine, v)) for v in sorted(views)}
        image_total += time.perf_counter() - t0
        buf = io.BytesIO()
        t0 = time.perf_counter()
        replay.write_episode_mcap(
            buf, machine, result, ssm_bytes=ssm, image=cache.get, library="bench"
        )
        total += time.perf_counter() - t0
        count += 1
        with_images += any(v is not None for v in cache.values())
    return {
        "episodes": count,
        "ms_per_episode": 1000 * total / max(count, 1),
        "image_ms_per_episode": 1000 * image_total / max(count, 1),
        "episodes_with_images": with_images,
    }


_STAGES = """
import collections, functools, json, sys, time
import replay
from replay.io import _batch, _runjob, _writer
from replay.kernel import _columnar, _columnar_parse
seconds = collections.Counter()

def timed(owner, name, label):
    real = getattr(owner, name)
    @functools.wraps(real)
    def wrapper(*args, **kwargs):
        t = time.process_time()
        try:
            return real(*args, **kwargs)
        finally:
            seconds[label] += time.process_time() - t
    setattr(owner, name, wrapper)

STAGES = [
    (_batch, "process_batch", "worker side: process_batch (decode + replay + tables)"),
    (_batch, "_prepare_line", "  decode, checks, machine compile and planning (cached)"),
    (_batch.WorkerState, "setup", "    of which planning (once per task)"),
    (_batch, "replay_columnar", "  columnar replay"),
    (_columnar_parse, "_fast_path", "      of which the polars tier"),
    (_columnar, "parse_steps", "    parse"),
    (_columnar, "simulate_episode", "    sequential loop (simulator memoised)"),
    (_columnar, "step_keys", "    point masks and memo keys"),
    (_columnar, "classify", "    classification"),
    (_columnar, "step_table", "    steps table (Arrow)"),
    (_columnar, "episode_tables", "    episodes and goals tables (Arrow)"),
    (_runjob.RunJob, "take", "main side: take (duplicates, tally, chunks, Parquet)"),
    (_writer.PartWriter, "_write_group", "  Parquet writing"),
]
for owner, name, label in STAGES:
    timed(owner, name, label)
runs, bench = json.loads(sys.argv[1])
t = time.process_time()
m = replay.replay_runs(runs, bench, sys.argv[2], force=True, progress=False)
total = time.process_time() - t
order = [(label, seconds[label]) for _, _, label in STAGES]
print(json.dumps({"total": total, "steps": m.content.totals.steps, "stages": order}))
"""


def stages(data: Path, out: Path) -> dict:
    """CPU seconds per stage of a one-worker replay of all runs (columnar engine)."""
    runs = [str(d) for d in sorted((data / "runs").iterdir()) if d.is_dir()]
    env = {**os.environ, "VGE_REPLAY_ENGINE": "columnar", "POLARS_MAX_THREADS": "1"}
    done = subprocess.run(
        [sys.executable, "-c", _STAGES, json.dumps([runs, str(data / "bench")]), str(out)],
        check=True,
        capture_output=True,
        text=True,
        env=env,
    )
    return json.loads(done.stdout.strip().splitlines()[-1])


def profile(data: Path, out: Path) -> list[tuple[str, float]]:
    """cProfile one-worker replay of the largest run (columnar engine); exclusive time by
    module group."""
    files = _episode_files(data)
    largest = max(files, key=lambda p: p.stat().st_size).parent
    prof = cProfile.Profile()
    prof.enable()
    replay.replay_runs([largest], data / "bench", out, force=True, progress=False)
    prof.disable()
    stats = pstats.Stats(prof)
    groups: dict[str, float] = defaultdict(float)
    for (filename, _, func), (_, _, tottime, _, _) in stats.stats.items():  # type: ignore[attr-defined]
        groups[_group(filename, func)] += tottime
    total = sum(groups.values())
    return sorted(((k, v / total) for k, v in groups.items()), key=lambda kv: -kv[1])


def _group(filename: str, func: str) -> str:
    path = Path(filename)
    if path.parent.name == "replay":
        stem = path.stem
        owner = (
            "runner"
            if stem in RUNNER_MODULES
            else "columnar"
            if stem.startswith("_columnar")
            else "core"
        )
        return f"{owner}: replay/{path.name}"
    if "pyarrow" in filename:
        return "lib: pyarrow"
    if "msgspec" in filename or "msgspec" in func:
        return "lib: msgspec"
    if filename == "~":
        return f"builtin: {func.split(' of ')[0].strip('<>')[:60]}"
    return "other: " + (path.parent.name + "/" + path.name if path.name else filename)


def _load() -> str:
    return " / ".join(f"{x:.1f}" for x in os.getloadavg())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("data", type=Path, help="directory with bench/ and runs/")
    parser.add_argument("--workers", default="1,2")
    parser.add_argument("--engines", default="columnar")
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--mcap-episodes", type=int, default=200)
    parser.add_argument("--stages", action="store_true")
    parser.add_argument("--profile", action="store_true")
    args = parser.parse_args()
    data: Path = args.data
    files = _episode_files(data)
    size = sum(p.stat().st_size for p in files)
    print(f"## Replay benchmark on {data}\n")
    print(
        f"- {len(files)} runs, {size / 1e6:.1f} MB of episode files, "
        f"python {sys.version.split()[0]}, {os.cpu_count()} CPUs, "
        f"load average at start {_load()}\n"
    )
    bare = bare_decoding(files)
    steps = bare["steps"]
    print("| measure | wall s | CPU s | steps/s (wall) | steps/s (CPU) |")
    print("|---|---:|---:|---:|---:|")
    print(f"| read + gunzip only | {bare['read_s']:.2f} | | | |")
    print(
        f"| bare decode, msgspec typed (`EpisodeLog`) | {bare['msgspec_s']:.2f} | "
        f"{bare['msgspec_cpu_s']:.2f} | {steps / bare['msgspec_s']:,.0f} | "
        f"{steps / bare['msgspec_cpu_s']:,.0f} |"
    )
    print(
        f"| bare decode, orjson untyped | {bare['orjson_s']:.2f} | | "
        f"{steps / bare['orjson_s']:,.0f} | |"
    )
    with tempfile.TemporaryDirectory() as tmp:
        results = {}
        for engine in args.engines.split(","):
            for workers in [int(w) for w in args.workers.split(",")]:
                tries = [
                    end_to_end(data, Path(tmp) / f"out-{engine}-{workers}", workers, engine)
                    for _ in range(args.repeat)
                ]
                r = min(tries, key=lambda t: t["main_cpu_s"] + t["workers_cpu_s"])
                results[(engine, workers)] = r
                assert r["steps"] == steps, (r["steps"], steps)
                # CPU-bound estimate on idle cores: the busiest process (main, or a worker's
                # share), or all the CPU spread over the machine's cores, whichever is slower
                cpu = r["main_cpu_s"] + r["workers_cpu_s"]
                bound = max(r["main_cpu_s"], r["workers_cpu_s"] / workers, cpu / CORES)
                print(
                    f"| replay end to end, {engine}, {workers} worker(s) | {r['wall_s']:.2f} | "
                    f"{cpu:.2f} | {r['steps'] / r['wall_s']:,.0f} | {r['steps'] / bound:,.0f} |"
                )
        print(
            "\n(steps/s (CPU): the rate on idle cores, from CPU times: steps divided by the CPU"
            " seconds of the busiest process (main, or a worker's share) or by all CPU seconds"
            f" over the machine's {CORES} cores, whichever is larger. With workers, the main"
            " process reads, writes Parquet and tallies; the workers decode and replay.)\n"
        )
        print(
            "| engine | workers | wall / bare decode | CPU / bare decode CPU | main CPU s |"
            " workers CPU s | peak RSS main (MB) | peak RSS largest worker (MB) | load after |"
        )
        print("|---|---:|---:|---:|---:|---:|---:|---:|---|")
        for (engine, workers), r in results.items():
            worker_rss = f"{r['worker_rss_mb']:.0f}" if workers > 1 else "-"
            cpu = r["main_cpu_s"] + r["workers_cpu_s"]
            print(
                f"| {engine} | {workers} | {r['wall_s'] / bare['msgspec_s']:.1f}x | "
                f"{cpu / bare['msgspec_cpu_s']:.1f}x | {r['main_cpu_s']:.1f} | "
                f"{r['workers_cpu_s']:.1f} | {r['main_rss_mb']:.0f} | {worker_rss} | {r['load']} |"
            )
        first = next(iter(results.values()))
        print(
            f"\n- {steps:,} steps, {first['episodes']:,} episodes, {first['quarantined']}"
            f" quarantined; load average at the end {_load()}"
        )
        m = mcap_ms_per_episode(data, args.mcap_episodes)
        print(
            f"- MCAP: {m['ms_per_episode']:.2f} ms per episode to write "
            f"({m['episodes']} episodes, {m['episodes_with_images']} with view images; "
            f"getting the images: {m['image_ms_per_episode']:.1f} ms per episode, cached per view)"
        )
        if args.stages:
            st = stages(data, Path(tmp) / "stages")
            n = st["steps"]
            print(
                f"\n| stage (1 worker, all runs, columnar; CPU {st['total']:.1f} s = "
                f"{1e6 * st['total'] / n:.1f} µs/step) | CPU s | µs/step |\n|---|---:|---:|"
            )
            for name, sec in st["stages"]:
                print(f"| {name} | {sec:.2f} | {1e6 * sec / n:.2f} |")
        if args.profile:
            print("\n| profile (1 worker, largest run): exclusive time | share |\n|---|---:|")
            shares = profile(data, Path(tmp) / "prof")
            for name, share in shares[:25]:
                print(f"| {name} | {100 * share:.1f}% |")
            runner = sum(s for n, s in shares if n.startswith("runner"))
            core = sum(s for n, s in shares if n.startswith("core"))
            print(
                f"\n- runner modules {100 * runner:.1f}%, core modules {100 * core:.1f}%, "
                f"rest (libraries, builtins) {100 * (1 - runner - core):.1f}%"
            )


if __name__ == "__main__":
    main()
