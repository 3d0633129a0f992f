"""`vge export OUT --format inspect|atif --out DIR`: replayed runs as Inspect logs or ATIF
trajectories, for the transcript tools that read them (docs/EXPORT.md)."""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

import typer

from ._options import episode_ids, ids_option, metrics_dir_option, out_argument

if TYPE_CHECKING:
    from rich.console import Console


def export_command(
    out: str = out_argument(),
    fmt: str = typer.Option(
        ...,
        "--format",
        "-f",
        help="inspect: one Inspect log per run (DIR/<run_id>.eval; `inspect view --log-dir DIR` "
        "opens them); atif: one ATIF trajectory per episode (DIR/<run_id>/<episode_id>.json).",
    ),
    dest: str = typer.Option(..., "--out", help="Directory to write into (created if needed)."),
    runs: str | None = ids_option("--runs", "Runs to export, comma-separated (default: all)."),
    episodes: str | None = ids_option(
        "--episodes", "Episodes to export, comma-separated (default: all, in the runs chosen)."
    ),
    images: str = typer.Option(
        "embed",
        "--images",
        help="embed: each view the agent looked at, downscaled to 512 px JPEG, beside the text "
        "it was shown; none: text only (much faster and smaller).",
    ),
    metrics_dir: str = metrics_dir_option(),
    progress: bool = typer.Option(
        True,
        "--progress/--no-progress",
        help="A progress bar on a terminal; elsewhere (a pipe, a log) a line per run.",
    ),
) -> None:
    """Write replayed runs as Inspect logs or ATIF trajectories.

    Each episode becomes a sample (inspect) or a trajectory (atif): the conversation the agent
    had, step by step, with the replay's verdicts as scores and metadata; a log's results
    hold the run's metrics. The same OUT gives the same bytes.
    """
    from rich.console import Console
    from rich.markup import escape
    from rich.progress import MofNCompleteColumn, Progress

    from ..export import export

    console = Console(stderr=True, highlight=False)
    # rich's own columns (description, bar, percentage, time left) and the episodes done
    bar = Progress(
        *Progress.get_default_columns(),
        MofNCompleteColumn(),
        console=console,
        disable=not (progress and console.is_terminal),
    )
    task = bar.add_task(fmt, total=None)
    lines = _RunLines(console) if progress and not console.is_terminal else None

    def tick(run_id: str, done: int, total: int) -> None:
        bar.update(task, description=f"export {escape(run_id)}", completed=done, total=total)
        if lines is not None:
            lines.tick(run_id, done, total)

    started = time.perf_counter()
    with bar:
        summary = export(
            out,
            fmt,
            dest,
            runs=episode_ids(runs, "--runs"),
            episodes=episode_ids(episodes, "--episodes"),
            images=images,
            metrics_dir=metrics_dir,
            progress=tick,
        )
    if lines is not None:
        lines.close()
    for line in summary.left_out:
        console.print(f"warning: {escape(line)}; left out of the export", soft_wrap=True)
    what = "log(s)" if fmt == "inspect" else "trajectories"
    console.print(
        f"wrote {summary.files:,} {what} ({summary.runs} run(s), {summary.episodes:,} episodes, "
        f"{summary.steps:,} steps) to {escape(str(dest))} in {time.perf_counter() - started:.1f} s",
        soft_wrap=True,
    )
    if fmt == "inspect":
        console.print(f"open them:  inspect view --log-dir {escape(str(dest))}", soft_wrap=True)


class _RunLines:
    """Progress in a pipe or a log: a line per run, once it is written (a run is written
    when the next one starts, or the export ends)."""

    def __init__(self, console: Console) -> None:
        self.console = console
        self.run: str | None = None
        self.first = self.done = self.total = 0
        self.started = time.perf_counter()

    def tick(self, run_id: str, done: int, total: int) -> None:
        if run_id != self.run:
            self.close()
            self.run, self.first = run_id, done - 1
        self.done, self.total = done, total

    def close(self) -> None:
        if self.run is None:
            return
        from rich.markup import escape

        now = time.perf_counter()
        self.console.print(
            f"exported {escape(self.run)}: {self.done - self.first:,} episodes in "
            f"{now - self.started:.1f} s ({self.done:,} of {self.total:,})",
            soft_wrap=True,
        )
        self.run, self.started = None, now


def register(app: typer.Typer) -> None:
    app.command("export")(export_command)
