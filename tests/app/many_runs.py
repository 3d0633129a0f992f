"""A replayed benchmark with many runs, for the charts that show one series per run.

`build_many_runs(root, n)`: the tiny synthetic benchmark (`vge synth --scale tiny`, nine
runs) and `n - 9` variants of its runs, each a copy under a run id of its own that keeps a
different subset of the source's episodes (so the variants' metrics differ), replayed into
`root/out`. Two variants test the labels: `random-cut`, whose run.json says it is not
complete (the pages label it `random-cut (incomplete)`), and one with a long run id
(`LONG_RUN_ID`). Used by the chart tests (tests/app/test_browser_charts.py).
"""

from __future__ import annotations

import gzip
import json
from pathlib import Path

import replay
from vge_analytics.synth import generate

LONG_RUN_ID = "variant-with-a-run-id-longer-than-any-label-limit"
INCOMPLETE_RUN_ID = "random-cut"


def _variant_ids(sources: list[str], extra: int) -> list[tuple[str, str]]:
    """(source run id, variant run id) of each variant: the sources in turn."""
    pairs = []
    for k in range(extra):
        source = sources[k % len(sources)]
        name = f"{source}-v{k:02d}"
        if k == 0:
            name = INCOMPLETE_RUN_ID
        elif k == 1:
            name = LONG_RUN_ID
        pairs.append((source, name))
    return pairs


def _write_variant(source: Path, target: Path, run_id: str, k: int) -> None:
    """A copy of the run `source` as `run_id`, without every (k % 4 + 2)-th episode."""
    header = json.loads((source / "run.json").read_text())
    header["run_id"] = run_id
    if run_id == INCOMPLETE_RUN_ID:
        header["meta"] = {**header.get("meta", {}), "complete": False}
    lines = gzip.decompress((source / "episodes.jsonl.gz").read_bytes()).splitlines(True)
    step = k % 4 + 2
    kept = [line for i, line in enumerate(lines) if i % step != step - 1]
    target.mkdir(parents=True)
    (target / "run.json").write_text(json.dumps(header, indent=2) + "\n")
    (target / "episodes.jsonl.gz").write_bytes(gzip.compress(b"".join(kept), mtime=0))


def build_many_runs(root: Path, n: int = 30) -> Path:
    """Synthesize the tiny benchmark under `root`, add variants up to `n` runs, replay them
    all into `root/out`; returns OUT."""
    generate(root / "synth", scale="tiny", seed=0, workers=1)
    runs_dir = root / "synth" / "runs"
    sources = sorted(p.name for p in runs_dir.iterdir() if p.is_dir())
    for k, (source, name) in enumerate(_variant_ids(sources, max(0, n - len(sources)))):
        _write_variant(runs_dir / source, runs_dir / name, name, k)
    out = root / "out"
    runs = sorted(p for p in runs_dir.iterdir() if p.is_dir())
    replay.replay_runs(runs, root / "synth" / "bench", out, progress=False)
    return out
