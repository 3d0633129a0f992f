"""`vge replay RUN... --bench BENCH --out OUT`: rescore logs into Parquet (and MCAP).

Exit codes: 0 every record replayed; 2 something was quarantined (see OUT/quarantine.jsonl);
1 fatal error (one-line message naming the file; `vge --debug` shows the traceback).
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

import typer

import replay

from ._options import episode_ids, max_record_bytes_option
from ._output import finish

if TYPE_CHECKING:
    from rich.table import Table


def _summary(manifest: replay.Manifest) -> Table:
    from rich import box
    from rich.markup import escape
    from rich.table import Table

    table = Table(box=box.SIMPLE_HEAD, pad_edge=False)
    table.add_column("run", no_wrap=True)
    table.add_column("status", no_wrap=True)
    for name in ("episodes", "quarantined", "steps", "truncated", "diverged"):
        table.add_column(name, justify="right", no_wrap=True, min_width=len(name))
    skipped = set(manifest.skipped)
    totals = [0] * 5
    for run_id in manifest.requested:
        c = manifest.run(run_id).counts
        values = [c.replayed, c.quarantined, c.steps, c.truncated_steps, c.diverged_steps]
        totals = [a + b for a, b in zip(totals, values, strict=True)]
        status = "skipped" if run_id in skipped else "replayed"
        style = "yellow" if c.quarantined else None
        table.add_row(escape(run_id), status, *(f"{v:,}" for v in values), style=style)
    if len(manifest.requested) > 1:
        table.add_row("total", "", *(f"{v:,}" for v in totals), style="bold")
    return table


def replay_command(
    runs: list[str] = typer.Argument(
        ...,
        help="Run directories (run.json + episodes.jsonl[.gz]): paths or URIs (s3://, gs://, "
        "file://).",
    ),
    bench: str = typer.Option(
        ..., "--bench", help="Benchmark directory (ssm/, tasks.jsonl): a path or a URI."
    ),
    out: str = typer.Option(
        ...,
        "--out",
        help="Output directory (tables, manifest, MCAP): a path or a URI such as "
        "s3://bucket/prefix (see docs/SCALE.md).",
    ),
    lam: float | None = typer.Option(
        None, "--lambda", help="Budget factor; overrides task and run.json lambda."
    ),
    mcap: bool = typer.Option(False, "--mcap", help="Also write one MCAP file per episode."),
    mcap_episodes: str | None = typer.Option(
        None,
        "--mcap-episodes",
        help="Comma-separated episode ids to write MCAP for (implies --mcap).",
    ),
    workers: int = typer.Option(1, "--workers", min=1, help="Worker processes."),
    ray: str | None = typer.Option(
        None,
        "--ray",
        metavar="[ADDRESS]",
        help="Replay on a Ray cluster instead of local workers: auto (this host's cluster or "
        "$RAY_ADDRESS; the default when no address follows), local (start one here), or an "
        "address. Needs pip install 'vge-analytics[ray]'.",
    ),
    force: bool = typer.Option(False, "--force", help="Replay runs even when up to date."),
    max_record_bytes: int = max_record_bytes_option(),
    progress: bool = typer.Option(True, "--progress/--no-progress", help="Progress bar on a TTY."),
) -> None:
    """Replay logged episodes against the SSMs into Parquet tables (and MCAP files).

    Writes the steps, episodes, goals and runs tables, and MCAP files on request.

    Exit code 0 when every record replayed, 2 when some were quarantined, 1 on fatal errors.
    """
    one_blas_thread()
    from rich.console import Console
    from rich.markup import escape

    console = Console(highlight=False)
    if not console.is_terminal:  # logs and pipes: do not squeeze the table into 80 columns
        console = Console(highlight=False, width=120)
    chosen, images = _mcap_inputs(bench, mcap, mcap_episodes)
    manifest = replay.replay_runs(
        runs,
        bench,
        out,
        lam=lam,
        workers=workers,
        mcap=mcap,
        mcap_episodes=chosen,
        force=force,
        progress=progress,
        image_source=images,
        ray=ray,
        max_record_bytes=max_record_bytes,
    )
    console.print(_summary(manifest))
    for run_id in manifest.skipped:
        console.print(f"{escape(run_id)}: up to date, skipped (--force redoes it)", soft_wrap=True)
    listed = escape(str(replay.io.quarantine_path(replay.location(out))))
    n = manifest.quarantined
    problem = f"{n:,} record(s) quarantined[/]: see {listed}" if n else None
    finish(console, f"wrote {escape(str(out))} ({replay.io.MANIFEST})", problem)


def _mcap_inputs(
    bench: str, mcap: bool, mcap_episodes: str | None
) -> tuple[list[str] | None, replay.ImageSource | None]:
    """The episodes given MCAP files (None: all) and the source of their pictures (None
    without MCAP), BENCH's refused pictures warned about."""
    if not (mcap or mcap_episodes):
        return checked_mcap_episodes(None, mcap_episodes), None
    # BENCH opened here once for both checks of MCAP's (0.75 s on the full benchmark)
    opened = replay.Benchmark.open(bench)
    chosen = checked_mcap_episodes(opened, mcap_episodes)
    warn_refused_pictures(opened, chosen, "left out of the MCAP files")
    from ..synth import image_source  # the renderer (PIL, 0.08 s) only for MCAP's pictures

    return chosen, image_source(bench)


def one_blas_thread() -> None:
    """OpenBLAS, which numpy loads, starts a thread per core that spins for a while after
    it starts (0.05 to 0.1 s of CPU in each process, the replay's workers included, which
    inherit the setting); the replay does no linear algebra. Set before numpy is imported;
    a value the user set stays."""
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


def warn_refused_pictures(opened: replay.Benchmark, episodes: list[str] | None, fate: str) -> None:
    """A warning on stderr for each view picture of the benchmark, of the devices of
    `episodes` (None: every device), that is there but refused (too large in bytes or pixels,
    or not a picture: PROTOCOL §1.1), saying its `fate`; `vge validate` lists the same."""
    devices = None
    if episodes is not None:
        devices = {opened.tasks[e].task.device_id for e in episodes if e in opened.tasks}
    for problem in replay.io.picture_problems(opened, devices):
        typer.echo(f"warning: {problem}; {fate}", err=True)


def checked_mcap_episodes(opened: replay.Benchmark | None, given: str | None) -> list[str] | None:
    """The episode ids of `--mcap-episodes`, checked against the benchmark's tasks (`opened`,
    given whenever `given` is): none of them a task is an error (a typo, not a request for no
    file), some of them a warning on stderr; each names the ids nearest to the first unknown
    one."""
    ids = episode_ids(given, "--mcap-episodes")
    if not ids:
        return ids
    assert opened is not None
    from .._nearest import nearest_hint

    unknown = [e for e in dict.fromkeys(ids) if e not in opened.tasks]
    if not unknown:
        return ids
    what = (
        f"not an episode of {opened.tasks_path}: "
        + ", ".join(map(repr, unknown[:5]))
        + (f" and {len(unknown) - 5:,} more" if len(unknown) > 5 else "")
        + nearest_hint(unknown[0], list(opened.tasks), "episode")
    )
    if len(unknown) == len(set(ids)):
        raise replay.ConfigError(f"--mcap-episodes selects no episode (no MCAP file): {what}")
    typer.echo(f"warning: --mcap-episodes: {what}", err=True)
    return ids


def register(app: typer.Typer) -> None:
    app.command("replay")(replay_command)
