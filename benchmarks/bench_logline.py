"""Benchmark of the episode-line decoder (not a test): `decode_line` (a line straight into the
kernel's step structs) against msgspec's `decode(episode_decoder, ...)` (depth check included)
on every line of every run, each followed by freeing what it made.

Usage:

    .venv/bin/python benchmarks/bench_logline.py /work/baseline/full [--runs sim-vlm-a ...]
        [--batch 512] [--rounds 3] [--lines N] [--once msgspec|decode_line|none]

Each run's lines are read first (`replay.io.iter_lines`, outside the timing). Then, `--rounds`
times, alternating which goes first: the CPU time (`time.process_time`) of decoding every
line, `--batch` lines at a time as a batch of `vge replay` holds them, the batch's results
dropped (freed) before the next; the garbage collector off, as in a batch. Prints per run:
lines, steps, lines accepted and declined (by reason), the least CPU per step of each decoder
and their ratio; then the same over all runs (docs/PERFORMANCE.md, *Episode lines decoded
straight into the kernel's structs*).

For instruction counts, which hold on a noisy machine: `--once NAME` decodes the lines once
with one decoder (`none`: none), untimed, and prints their steps; run it under `valgrind
--tool=callgrind` for each NAME: the difference of a decoder's total and `none`'s is its
instructions (`--lines` takes the first N lines of each run).
"""

from __future__ import annotations

import argparse
import gc
import time
from collections import Counter
from pathlib import Path


def _timed(decode, lines: list[bytes], batch: int) -> float:
    """CPU seconds to decode `lines` (a batch at a time) and free the results."""
    started = time.process_time()
    for at in range(0, len(lines), batch):
        made = [decode(raw) for raw in lines[at : at + batch]]
        del made
    return time.process_time() - started


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("data", type=Path, help="directory with runs/")
    parser.add_argument("--runs", nargs="*", help="run names (default: every run)")
    parser.add_argument("--batch", type=int, default=512)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--lines", type=int, help="the first N lines of each run")
    parser.add_argument("--once", choices=["msgspec", "decode_line", "none"])
    args = parser.parse_args()

    import replay.io
    from replay.kernel import decline_reason, decode_line, nested_beyond

    decoder = replay.io.episode_decoder

    def with_msgspec(raw: bytes) -> object:
        """`replay.io`'s decode of a line: the depth check, then msgspec."""
        if nested_beyond(raw, 256) >= 0:
            raise ValueError("too deep")
        return decoder.decode(raw)

    names = args.runs or sorted(p.name for p in (args.data / "runs").iterdir() if p.is_dir())
    gc.disable()
    total = Counter()
    if not args.once:
        print(
            f"{'run':<16} {'lines':>7} {'steps':>8} {'accepted':>8}  {'msgspec':>8} "
            f"{'decode_line':>11} {'ratio':>6}  declined"
        )
    for name in names:
        path = replay.io.episodes_file(str(args.data / "runs" / name))
        lines = [raw for _, raw in replay.io.iter_lines(path)][: args.lines]
        steps = sum(len(decoder.decode(raw).steps) for raw in lines)
        if args.once:
            if args.once != "none":
                _timed(
                    {"msgspec": with_msgspec, "decode_line": decode_line}[args.once],
                    lines,
                    args.batch,
                )
            print(f"{name}: {len(lines):,} lines, {steps:,} steps")
            continue
        reasons = Counter(decline_reason(raw) for raw in lines)
        accepted = reasons.pop(None, 0)
        best = {"msgspec": float("inf"), "decode_line": float("inf")}
        for r in range(args.rounds):
            order = [("msgspec", with_msgspec), ("decode_line", decode_line)]
            for label, fn in order if r % 2 == 0 else reversed(order):
                best[label] = min(best[label], _timed(fn, lines, args.batch))
        total.update({"lines": len(lines), "steps": steps, "accepted": accepted, **best})
        total.update({f"declined: {k}": v for k, v in reasons.items()})
        _row(name, len(lines), steps, accepted, best, reasons)
    if args.once:
        return
    declined = Counter({k[10:]: v for k, v in total.items() if k.startswith("declined: ")})
    _row("all", total["lines"], total["steps"], total["accepted"], total, declined)


def _row(name: str, lines: int, steps: int, accepted: int, best, reasons: Counter) -> None:
    ms, ours = (best[k] / steps * 1e6 for k in ("msgspec", "decode_line"))
    why = ", ".join(f"{v:,} {k}" for k, v in sorted(reasons.items())) or "-"
    print(
        f"{name:<16} {lines:>7,} {steps:>8,} {accepted:>8,}  {ms:>8.3f} {ours:>11.3f} "
        f"{ms / ours:>6.1f}  {why}"
    )


if __name__ == "__main__":
    main()
