"""Benchmark of `vge replay` (not a test): the kernel against bare decoding and the reference.

Usage (on the full synthetic benchmark):

    vge synth --out /tmp/vge-full --scale full --seed 0
    .venv/bin/python benchmarks/bench_replay.py /tmp/vge-full [--workers 1,2]
        [--reference] [--ray 1,2] [--repeat N] [--stages] [--mcap-episodes N]

DATA is a directory with `bench/` and `runs/*` (what `vge synth` writes). Everything is
measured in one run, so that ratios hold on a shared, noisy machine:
- bare decoding: the episode files read and decoded line by line with msgspec into the same
  typed `EpisodeLog` records the replay uses (the floor any replay of these logs pays);
- end to end (logs -> Parquet, `replay_runs(..., force=True)`), each configuration in a
  fresh subprocess: the kernel with each worker count, the reference engine
  (`VGE_REPLAY_ENGINE=reference`, with `--reference`), and Ray (`--ray 1,2`: a cluster of
  that many one-CPU nodes on loopback, `ray.cluster_utils`); wall and CPU seconds of every
  process involved, peak RSS, and a sha256 over the output directory, which must be the
  same for all (the byte-identity the tests check on smaller data);
- with `--stages`: CPU time per stage of a one-worker kernel replay of all runs, from
  timers around the stage functions;
- MCAP: milliseconds per episode of `write_episode_mcap`.
`--repeat N` keeps, per configuration, the try with the least CPU time. Prints a Markdown
report (docs/PERFORMANCE.md records one).
"""

from __future__ import annotations

import argparse
import gzip
import io
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import replay
from replay.io import episode_decoder
from vge_analytics.synth import BENCH_DIR, RUNS_DIR, image_source

CORES = os.cpu_count() or 1


def _episode_files(data: Path) -> list[Path]:
    return sorted(replay.episodes_file(d).local for d in (data / RUNS_DIR).iterdir() if d.is_dir())


def _read(path: Path) -> bytes:
    raw = path.read_bytes()
    return gzip.decompress(raw) if path.suffix == ".gz" else raw


def bare_decoding(files: list[Path]) -> dict[str, float]:
    """Seconds to read + decode every line with msgspec (typed); step count."""
    steps = 0
    t0, c0 = time.perf_counter(), time.process_time()
    for path in files:
        for line in _read(path).splitlines():
            if line.strip():
                steps += len(episode_decoder.decode(line).steps)
    return {
        "steps": steps,
        "wall_s": time.perf_counter() - t0,
        "cpu_s": time.process_time() - c0,
    }


# The child replays, then reports its own CPU and that of every process it started (pool
# workers are reaped, so RUSAGE_CHILDREN holds them; Ray's raylets and workers are alive
# until shutdown, so psutil reads them first), and hashes the output directory.
_CHILD = """
import hashlib, json, os, resource, sys, time
from pathlib import Path
runs, bench, out, workers, nodes = json.loads(sys.argv[1])
cluster = None
if nodes:
    import ray
    from ray.cluster_utils import Cluster
    head = {"num_cpus": 1, "node_ip_address": "127.0.0.1", "include_dashboard": False}
    cluster = Cluster(initialize_head=True, head_node_args=head)
    for _ in range(nodes - 1):
        cluster.add_node(num_cpus=1, node_ip_address="127.0.0.1")
    ray.init(address=cluster.address, log_to_driver=False)
    cluster.wait_for_nodes()
    def tree_cpu():
        # CPU seconds of every live descendant of this process, from /proc (Linux)
        tick = os.sysconf("SC_CLK_TCK")
        stats = {}
        for entry in os.listdir("/proc"):
            if entry.isdigit():
                try:
                    text = open(f"/proc/{entry}/stat").read()
                except OSError:
                    continue
                fields = text[text.rindex(")") + 2:].split()
                stats[int(entry)] = (int(fields[1]), (int(fields[11]) + int(fields[12])) / tick)
        mine, total, grew = {os.getpid()}, 0.0, True
        while grew:
            grew = False
            for pid, (ppid, cpu) in stats.items():
                if ppid in mine and pid not in mine:
                    mine.add(pid)
                    total += cpu
                    grew = True
        return total
    ray_cpu0 = tree_cpu()
import replay
t0 = time.perf_counter()
m = replay.replay_runs(runs, bench, out, workers=workers, force=True, progress=False,
                       ray="auto" if nodes else None)
wall = time.perf_counter() - t0
me = resource.getrusage(resource.RUSAGE_SELF)
kids = resource.getrusage(resource.RUSAGE_CHILDREN)
others = kids.ru_utime + kids.ru_stime
if nodes:
    others = tree_cpu() - ray_cpu0
    used = dict(m.nodes)
digest = hashlib.sha256()
for p in sorted(Path(out).rglob("*")):
    if p.is_file() and ".replay" not in p.parts:
        digest.update(str(p.relative_to(out)).encode() + b"\\0" + p.read_bytes())
print(json.dumps({
    "wall_s": wall,
    "main_cpu_s": me.ru_utime + me.ru_stime,
    "others_cpu_s": others,
    "steps": m.content.totals.steps,
    "episodes": m.content.totals.replayed,
    "quarantined": m.content.totals.quarantined,
    "main_rss_mb": me.ru_maxrss / 1024,
    "worker_rss_mb": kids.ru_maxrss / 1024,
    "nodes_used": len(used) if nodes else 0,
    "sha256": digest.hexdigest(),
}))
if cluster is not None:
    ray.shutdown()
    cluster.shutdown()
"""


def end_to_end(
    data: Path, out: Path, *, workers: int = 1, engine: str = "kernel", nodes: int = 0
) -> dict:
    runs = [str(d) for d in sorted((data / RUNS_DIR).iterdir()) if d.is_dir()]
    arg = json.dumps([runs, str(data / BENCH_DIR), str(out), workers, nodes])
    env = {
        **os.environ,
        "VGE_REPLAY_ENGINE": engine,
        "POLARS_MAX_THREADS": "1",
        "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER": "0",  # keep Ray's nodes on loopback
    }
    done = subprocess.run(
        [sys.executable, "-c", _CHILD, arg], check=True, capture_output=True, text=True, env=env
    )
    result = json.loads(done.stdout.strip().splitlines()[-1])
    result["load"] = _load()
    return result


_STAGES = """
import cProfile, json, pstats, sys, time
from pathlib import Path
import replay
runs, bench = json.loads(sys.argv[1])
profile = cProfile.Profile(time.process_time)
t = time.process_time()
profile.enable()
m = replay.replay_runs(runs, bench, sys.argv[2], force=True, progress=False)
profile.disable()
total = time.process_time() - t
cumulative = {}  # (file, function) -> CPU seconds in it and what it called
for (file, _, name), (_, _, _, seconds, _) in pstats.Stats(profile).stats.items():
    key = "/".join(Path(file).parts[-2:]) + ":" + name
    cumulative[key] = cumulative.get(key, 0.0) + seconds
print(json.dumps({"total": total, "steps": m.content.totals.steps, "cumulative": cumulative}))
"""

STAGES = [
    ("io/_batch.py:_prepare_lines", "decode and check each line (msgspec), plan per task (cached)"),
    ("io/_worker.py:setup", "  of which planning (once per task and process)"),
    ("kernel/_batch.py:replay_kernel", "kernel: parse, simulate, classify (C)"),
    ("kernel/_assemble.py:tables", "kernel: columns to Arrow tables"),
    ("io/_batch.py:_counts", "batch tallies (Arrow compute)"),
    ("io/_files.py:write_part", "Parquet parts (written by the worker)"),
    ("io/_job.py:take", "main process: take reports, duplicates, quarantine"),
    ("io/_job.py:commit", "main process: commit (manifest, swap in)"),
]
"""(file:function as the profiler names it, label) of each stage, timed by the CPU seconds
spent in the function and what it calls; the kernel's row leaves out the Arrow tables it
builds, which have their own row."""


def stages(data: Path, out: Path) -> dict:
    """CPU seconds per stage of a one-worker kernel replay of all runs, under Python'sprofiler (which adds its own cost to every Python call: the stages are read as shares)."""
    runs = [str(d) for d in sorted((data / RUNS_DIR).iterdir()) if d.is_dir()]
    env = {**os.environ, "VGE_REPLAY_ENGINE": "kernel", "POLARS_MAX_THREADS": "1"}
    done = subprocess.run(
        [sys.executable, "-c", _STAGES, json.dumps([runs, str(data / BENCH_DIR)]), str(out)],
        check=True,
        capture_output=True,
        text=True,
        env=env,
    )
    got = json.loads(done.stdout.strip().splitlines()[-1])
    seconds = {key: got["cumulative"].get(key, 0.0) for key, _ in STAGES}
    seconds["kernel/_batch.py:replay_kernel"] -= seconds["kernel/_assemble.py:tables"]
    order = [(label, seconds[key]) for key, label in STAGES]
    return {"total": got["total"], "steps": got["steps"], "stages": order}


def mcap_ms_per_episode(data: Path, n: int) -> dict[str, float]:
    """Replay `n` episodes of the largest run; time `write_episode_mcap` alone, with the
    view images (the CLI's image source) fetched beforehand."""
    bench = replay.Benchmark.open(data / BENCH_DIR)
    images = image_source(data / BENCH_DIR)
    largest = max(_episode_files(data), key=lambda p: p.stat().st_size)
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
        cache = {v: replay.io.as_view_image(images(machine, v)) for v in sorted(views)}
        image_total += time.perf_counter() - t0
        buf = io.BytesIO()
        t0 = time.perf_counter()
        replay.write_episode_mcap(
            buf, machine, result, ssm_bytes=ssm, image=cache.get
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


def engine_core(data: Path) -> dict[str, float]:
    """CPU µs per step of the engines alone on the largest run, in this process: the same
    decoded episodes with their plans (prepared beforehand, not timed) to the same three
    Arrow tables, by `replay_episode` + `rows_to_table` and by the kernel, in batches of
    4,096 episodes; each timed twice, the second time (machines and goals warm) kept."""
    from replay.io import reference_tables, worker_state
    from replay.kernel import EpisodeInput, replay_kernel

    state = worker_state(str(data / BENCH_DIR))
    largest = max(_episode_files(data), key=lambda p: p.stat().st_size)
    episodes = []
    for line in _read(largest).splitlines():
        log = episode_decoder.decode(line)
        task = state.bench.tasks[log.episode_id].task
        machine = state.bench.machine(task.device_id)
        episodes.append(EpisodeInput(machine, task, state.setup(machine, task), log, 5.0))
    steps = sum(len(e.log.steps) for e in episodes)
    batches = [episodes[i : i + 4096] for i in range(0, len(episodes), 4096)]

    def reference() -> None:
        for batch in batches:
            reference_tables(
                [
                    replay.replay_episode(
                        e.machine, e.task, e.log, lam=e.lam, run_id="r", model="m",
                        agent_kind="vlm", setup=e.setup,
                    )
                    for e in batch
                ]
            )

    def kernel() -> None:
        for batch in batches:
            replay_kernel(batch, run_id="r", model="m", agent_kind="vlm")

    out = {"steps": float(steps)}
    for name, fn in (("reference", reference), ("kernel", kernel)):
        for _ in range(2):
            c0 = time.process_time()
            fn()
            out[name] = 1e6 * (time.process_time() - c0) / steps
    return out


def _load() -> str:
    return " / ".join(f"{x:.1f}" for x in os.getloadavg())


def _best(tries: list[dict]) -> dict:
    return min(tries, key=lambda t: t["main_cpu_s"] + t["others_cpu_s"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("data", type=Path, help="directory with bench/ and runs/")
    parser.add_argument("--workers", default="1,2", help="kernel worker counts")
    parser.add_argument("--reference", action="store_true", help="also the reference engine")
    parser.add_argument("--ray", default="", help="Ray node counts, e.g. 1,2")
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--mcap-episodes", type=int, default=200)
    parser.add_argument("--stages", action="store_true")
    args = parser.parse_args()
    data: Path = args.data
    files = _episode_files(data)
    size = sum(p.stat().st_size for p in files)
    print(f"## Replay benchmark on {data}\n")
    print(
        f"- {len(files)} runs, {size / 1e6:.1f} MB of episode files, "
        f"python {sys.version.split()[0]}, {CORES} CPUs, load average at start {_load()}\n"
    )
    bare = bare_decoding(files)
    steps = bare["steps"]
    configs: list[tuple[str, dict]] = []
    for w in [int(w) for w in args.workers.split(",") if w]:
        configs.append((f"kernel, {w} worker{'s' * (w > 1)}", {"workers": w}))
    for n in [int(n) for n in args.ray.split(",") if n]:
        configs.append((f"kernel on Ray, {n} node{'s' * (n > 1)} x 1 CPU", {"nodes": n}))
    if args.reference:
        configs.append(("reference engine, 1 worker", {"engine": "reference"}))
    results: dict[str, dict] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for i, (label, kw) in enumerate(configs):
            tries = [end_to_end(data, Path(tmp) / f"out-{i}", **kw) for _ in range(args.repeat)]
            results[label] = _best(tries)
            assert results[label]["steps"] == steps, (label, results[label]["steps"], steps)
        print(
            "| measure | wall s | CPU s (all processes) | steps/s (wall) | wall / bare decode |"
            " peak RSS main MB | peak RSS worker MB | output sha256 | load after |"
        )
        print("|---|---:|---:|---:|---:|---:|---:|---|---|")
        print(
            f"| bare decode, msgspec typed (`EpisodeLog`) | {bare['wall_s']:.2f} | "
            f"{bare['cpu_s']:.2f} | {steps / bare['wall_s']:,.0f} | 1.0x | | | | |"
        )
        for label, r in results.items():
            cpu = r["main_cpu_s"] + r["others_cpu_s"]
            worker_rss = f"{r['worker_rss_mb']:.0f}" if r["worker_rss_mb"] > 0 else "-"
            if "Ray" in label:
                worker_rss = f"- ({r['nodes_used']} nodes used)"
            print(
                f"| {label} | {r['wall_s']:.2f} | {cpu:.2f} | {steps / r['wall_s']:,.0f} | "
                f"{r['wall_s'] / bare['wall_s']:.1f}x | {r['main_rss_mb']:.0f} | {worker_rss} | "
                f"`{r['sha256'][:12]}` | {r['load']} |"
            )
        digests = {r["sha256"] for r in results.values()}
        first = next(iter(results.values()))
        print(
            f"\n- {steps:,} steps, {first['episodes']:,} episodes, {first['quarantined']}"
            f" quarantined; outputs {'byte-identical' if len(digests) == 1 else 'DIFFER'}"
            f" across the {len(results)} configurations; load average at the end {_load()}"
        )
        ref = results.get("reference engine, 1 worker")
        one = results.get("kernel, 1 worker")
        if ref and one:
            print(f"- kernel vs reference, 1 worker: {ref['wall_s'] / one['wall_s']:.1f}x faster")
        core = engine_core(data)
        print(
            f"- engines alone (largest run, {core['steps']:,.0f} steps, decoded and planned "
            f"beforehand, to the same Arrow tables, warm): reference {core['reference']:.2f} "
            f"µs/step, kernel {core['kernel']:.2f} µs/step: "
            f"{core['reference'] / core['kernel']:.1f}x faster"
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
                f"\n| stage (kernel, 1 worker, all runs; CPU {st['total']:.2f} s = "
                f"{1e6 * st['total'] / n:.2f} µs/step) | CPU s | µs/step |\n|---|---:|---:|"
            )
            for name, sec in st["stages"]:
                print(f"| {name} | {sec:.2f} | {1e6 * sec / n:.2f} |")
        if len(digests) != 1:
            sys.exit("outputs differ between configurations")


if __name__ == "__main__":
    main()
