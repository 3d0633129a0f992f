"""What `vge export` costs, beside what any reader of OUT pays, measured in the same run.

    python benchmarks/bench_export.py OUT [--formats inspect,atif] [--images none] [--runs ID,...]

Every measure is a fresh process (`wait4` gives its CPU time and peak resident memory):

- *vge metrics*: `vge metrics OUT --format csv`, the paper's table over every step;
- *read every episode*: the export's own reading with nothing written, the floor of an
  export (`tests/vge_analytics/export/reading.py`);
- *export F*: `vge export OUT --format F --out DIR --images I --no-progress` into a
  temporary directory, its size measured, then deleted.

Results go to stdout as a markdown table (docs/PERFORMANCE.md, section "Export"). The
machine is shared and noisy: compare the rows of one run, not runs.
"""

from __future__ import annotations

import argparse
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.vge_analytics.export.reading import read_command  # noqa: E402


def run(cmd: list[str]) -> tuple[float, float, int, str]:
    """(wall s, CPU s, peak resident bytes, stdout and stderr) of `cmd`, from the kernel's
    accounting of that one process (`wait4`)."""
    with tempfile.TemporaryFile() as sink:
        started = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=sink, stderr=subprocess.STDOUT, cwd=ROOT)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - started
        sink.seek(0)
        text = sink.read().decode(errors="replace")
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{text}")
    return wall, usage.ru_utime + usage.ru_stime, usage.ru_maxrss * 1024, text


def size_of(path: Path) -> int:
    return sum(p.stat().st_size for p in path.rglob("*") if p.is_file())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--formats", default="inspect,atif")
    parser.add_argument("--images", default="none", choices=("none", "embed"))
    parser.add_argument("--runs", default="", help="Runs to export (default: all).")
    args = parser.parse_args()
    py = sys.executable
    selection = ["--runs", args.runs] if args.runs else []

    print(
        f"machine: {os.cpu_count()} CPUs, Python {platform.python_version()}, "
        f"load average {os.getloadavg()[0]:.1f} at the start",
        file=sys.stderr,
    )
    rows = []
    wall, cpu, peak, text = run(
        [py, "-m", "vge_analytics.cli", "metrics", str(args.out), "-f", "csv"]
    )
    rows.append(("vge metrics (the paper's table)", wall, cpu, peak, None))
    wall, cpu, peak, text = run(read_command(args.out, args.runs))
    steps = int(text.split()[3])
    rows.append(("read every episode (the export's reads, nothing written)", wall, cpu, peak, None))
    for fmt in args.formats.split(","):
        dest = Path(tempfile.mkdtemp(prefix=f"bench-export-{fmt}-"))
        try:
            cmd = [py, "-m", "vge_analytics.cli", "export", str(args.out), "--format", fmt]
            cmd += ["--out", str(dest), "--images", args.images, "--no-progress", *selection]
            wall, cpu, peak, text = run(cmd)
            rows.append(
                (
                    f"vge export --format {fmt} --images {args.images}",
                    wall,
                    cpu,
                    peak,
                    size_of(dest),
                )
            )
        finally:
            shutil.rmtree(dest, ignore_errors=True)

    print(f"load average {os.getloadavg()[0]:.1f} at the end; {steps:,} steps", file=sys.stderr)
    print("| measure | wall s | CPU s | steps/s (CPU) | peak RSS MB | written MB |")
    print("|---|---:|---:|---:|---:|---:|")
    for name, wall, cpu, peak, written in rows:
        size = f"{written / 1e6:,.0f}" if written is not None else ""
        print(
            f"| {name} | {wall:,.1f} | {cpu:,.1f} | {steps / cpu:,.0f} | {peak / 2**20:,.0f} | {size} |"
        )


if __name__ == "__main__":
    main()
