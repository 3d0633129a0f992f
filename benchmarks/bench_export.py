"""What `vge export` costs, beside what any reader of OUT pays and beside a baseline's export,
measured in the same run, alternating: docs/PERFORMANCE.md, section "Export".

    python benchmarks/bench_export.py OUT [--formats inspect,atif] [--images none]
        [--runs ID,...] [--base DIR] [--repeat 1]

Every measure is a fresh process (`wait4` gives its CPU time and peak resident memory):

- *vge metrics*: `vge metrics OUT --format csv`, the paper's table over every step;
- *read every episode*: the export's own reading with nothing written, the floor of an
  export (`tests/vge_analytics/export/reading.py`);
- *export F*: `vge export OUT --format F --out DIR --images I --no-progress` into a
  temporary directory, its size measured, then deleted. Exports are cold: each process has
  an empty cache of rendered views (`VGE_CACHE_DIR`), so with `--images embed` every
  picture is rendered again, as on a first export.

With `--base DIR` (a checkout of the baseline with its `.venv`, e.g. `/work/main`), each
export is also run by the baseline's code, the two alternating (the baseline first in odd
repeats); `--repeat N` runs the whole sequence N times. Results go to stdout as a markdown
table with the ratios the issue asks for (Inspect's CPU time over ATIF's and over
reading's). The machine is shared and noisy: compare the rows of one run, not runs.
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


def run(
    cmd: list[str], cwd: Path, env: dict[str, str] | None = None
) -> tuple[float, float, int, str]:
    """(wall s, CPU s, peak resident bytes, stdout and stderr) of `cmd`, from the kernel's
    accounting of that one process (`wait4`)."""
    with tempfile.TemporaryFile() as sink:
        started = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=sink, stderr=subprocess.STDOUT, cwd=cwd, env=env)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - started
        sink.seek(0)
        text = sink.read().decode(errors="replace")
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{text}")
    return wall, usage.ru_utime + usage.ru_stime, usage.ru_maxrss * 1024, text


def size_of(path: Path) -> int:
    return sum(p.stat().st_size for p in path.rglob("*") if p.is_file())


def python_of(tree: Path) -> str:
    """The interpreter of a checkout: its own `.venv`, else this one."""
    venv = tree / ".venv" / "bin" / "python"
    return str(venv) if venv.exists() else sys.executable


def export_once(tree: Path, out: Path, fmt: str, images: str, runs: str) -> tuple:
    """One cold export by the code of `tree`: (wall, CPU, peak, bytes written)."""
    dest = Path(tempfile.mkdtemp(prefix=f"bench-export-{fmt}-"))
    cache = Path(tempfile.mkdtemp(prefix="bench-export-cache-"))
    env = {**os.environ, "VGE_CACHE_DIR": str(cache), "PYTHONPATH": str(tree)}
    cmd = [python_of(tree), "-m", "vge_analytics.cli", "export", str(out), "--format", fmt]
    cmd += ["--out", str(dest), "--images", images, "--no-progress"]
    cmd += ["--runs", runs] if runs else []
    try:
        wall, cpu, peak, _ = run(cmd, tree, env)
        return wall, cpu, peak, size_of(dest)
    finally:
        shutil.rmtree(dest, ignore_errors=True)
        shutil.rmtree(cache, ignore_errors=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--formats", default="inspect,atif")
    parser.add_argument("--images", default="none", choices=("none", "embed"))
    parser.add_argument("--runs", default="", help="Runs to export (default: all).")
    parser.add_argument("--base", type=Path, help="A checkout of the baseline, with .venv.")
    parser.add_argument("--repeat", type=int, default=1)
    args = parser.parse_args()
    out = args.out.resolve()
    trees = {"this": ROOT} | ({"base": args.base.resolve()} if args.base else {})

    print(
        f"machine: {os.cpu_count()} CPUs, Python {platform.python_version()}, "
        f"load average {os.getloadavg()[0]:.1f} at the start",
        file=sys.stderr,
    )
    rows: list[tuple[str, str, float, float, int, int | None]] = []
    wall, cpu, peak, _ = run(
        [sys.executable, "-m", "vge_analytics.cli", "metrics", str(out), "-f", "csv"], ROOT
    )
    rows.append(("vge metrics (the paper's table)", "this", wall, cpu, peak, None))
    for repeat in range(args.repeat):
        wall, cpu, peak, text = run(read_command(out, args.runs), ROOT)
        steps = int(text.split()[3])
        rows.append(("read every episode (nothing written)", "this", wall, cpu, peak, None))
        order = list(trees.items())
        if repeat % 2 == 0:
            order.reverse()  # the baseline first, then this code; the other way next time
        for fmt in args.formats.split(","):
            for code, tree in order:
                measured = export_once(tree, out, fmt, args.images, args.runs)
                rows.append((f"vge export --format {fmt} --images {args.images}", code, *measured))
                print(f"{rows[-1][0]} ({code}): {measured[1]:.1f} s CPU", file=sys.stderr)

    print(f"load average {os.getloadavg()[0]:.1f} at the end; {steps:,} steps", file=sys.stderr)
    print("| measure | code | wall s | CPU s | steps/s (CPU) | peak RSS MB | written MB |")
    print("|---|---|---:|---:|---:|---:|---:|")
    for name, code, wall, cpu, peak, written in rows:
        size = f"{written / 1e6:,.0f}" if written is not None else ""
        print(
            f"| {name} | {code} | {wall:,.1f} | {cpu:,.1f} | {steps / cpu:,.0f} "
            f"| {peak / 2**20:,.0f} | {size} |"
        )
    print()
    _ratios(rows, args.images)


def _ratios(rows: list[tuple], images: str) -> None:
    """Inspect's CPU time over ATIF's and over reading's, per code (means over repeats)."""

    def mean(name: str, code: str) -> float | None:
        got = [r[3] for r in rows if r[0] == name and r[1] == code]
        return sum(got) / len(got) if got else None

    read = mean("read every episode (nothing written)", "this")
    for code in ("base", "this"):
        inspect = mean(f"vge export --format inspect --images {images}", code)
        atif = mean(f"vge export --format atif --images {images}", code)
        if inspect is None:
            continue
        parts = [f"inspect / read {inspect / read:.2f}"]
        if atif is not None:
            parts.append(f"inspect / atif {inspect / atif:.2f}")
        print(f"- {code}: " + ", ".join(parts) + " (CPU time)")


if __name__ == "__main__":
    main()
