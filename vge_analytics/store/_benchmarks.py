"""Which benchmark each run of OUT was replayed against, and the check that the runs a
comparison pairs share one (`check_same_benchmark`).

A comparison pairs episodes by id; runs of two benchmarks can share ids while their tasks
differ (another instruction, goal or device behind the same `AirFryer_000-00`), and pairing
them gives numbers that look right and mean nothing. The manifest knows each run's benchmark
by content: the SHA-256 of its `tasks.jsonl` and of the SSM of every device its episodes use
(PROTOCOL §7). Two runs are of one benchmark when their tasks digests are equal and every
device both use has the same SSM digest; a run whose manifest entry lacks a digest (written
before they were recorded) is not refused.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import replay

from .._errors import DifferentBenchmarksError, OutputDirError
from ._contents import read_manifest
from ._store import Store


@dataclass(frozen=True)
class Benchmark:
    """A run's benchmark, as its manifest entry records it."""

    path: str
    """BENCH as the replay was given it."""
    tasks: str | None
    """SHA-256 of its tasks.jsonl (None: not recorded)."""
    ssm: dict[str, str]
    """SHA-256 of the SSM of each device the run's episodes use."""

    def differs(self, other: Benchmark) -> str | None:
        """What tells the two apart (None: nothing recorded does)."""
        if self.tasks and other.tasks and self.tasks != other.tasks:
            return f"tasks.jsonl sha256 {self.tasks[:12]} and {other.tasks[:12]}"
        for device in sorted(self.ssm.keys() & other.ssm.keys()):
            if self.ssm[device] != other.ssm[device]:
                mine, theirs = self.ssm[device][:12], other.ssm[device][:12]
                return f"the SSM of {device}: sha256 {mine} and {theirs}"
        return None


def _digest(ref: object) -> str | None:
    return ref.get("sha256") if isinstance(ref, dict) else None


def _manifest_runs(store: Store) -> list:
    """The manifest's run entries, whole: the store keeps only what its queries read (no
    digests), so the manifest is read again, once per check."""
    if store.in_memory:
        return store.manifest.get("runs", [])
    try:
        return (read_manifest(replay.location(store.out)) or {}).get("runs", [])
    except OutputDirError:
        return store.manifest.get("runs", [])


def benchmark_of(store: Store, run_id: str, runs: list | None = None) -> Benchmark:
    """The benchmark `run_id` of OUT was replayed against (from OUT's manifest; `runs`: its
    run entries, read already)."""
    for entry in _manifest_runs(store) if runs is None else runs:
        if entry.get("run_id") == run_id:
            inputs = entry.get("inputs") or {}
            ssm = inputs.get("ssm") or {}
            digests = {device: _digest(ref) for device, ref in ssm.items()}
            return Benchmark(
                path=str(inputs.get("bench", "")),
                tasks=_digest(inputs.get("tasks")),
                ssm={d: s for d, s in digests.items() if s},
            )
    return Benchmark(path="", tasks=None, ssm={})  # not in the manifest: nothing to tell


def check_same_benchmark(store: Store, run_ids: Sequence[str], *, allow: bool = False) -> None:
    """Raise `DifferentBenchmarksError` (one line naming two runs and what differs) when the
    runs were replayed against different benchmarks, unless `allow`."""
    if allow:
        return
    runs = list(dict.fromkeys(run_ids))
    entries = _manifest_runs(store)
    seen = [(run, benchmark_of(store, run, entries)) for run in runs]
    for i, (run_a, bench_a) in enumerate(seen):
        for run_b, bench_b in seen[i + 1 :]:
            why = bench_a.differs(bench_b)
            if why is not None:
                raise DifferentBenchmarksError(
                    f"runs {run_a!r} and {run_b!r} of {store.out} were replayed against "
                    f"different benchmarks ({bench_a.path} and {bench_b.path}: {why}); their "
                    "episodes share ids, not tasks, so they are not compared"
                )


__all__ = ["Benchmark", "benchmark_of", "check_same_benchmark"]
