"""`export(out, fmt, dest, ...)`: the selected runs of OUT written in one of the formats, a run
at a time and an episode at a time (`_source` fetches them in batches), with a callback per
episode for a progress bar."""

from __future__ import annotations

import importlib.util
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import replay
from replay.io import make_folders, staged_path, write_atomic

from ..metrics import load_metrics
from ._pictures import Views
from ._source import Episode, Run, Source, open_source

FORMATS: tuple[str, ...] = ("inspect", "atif")
IMAGES: tuple[str, ...] = ("embed", "none")
NEEDS: dict[str, str] = {"inspect": "inspect_ai", "atif": "atif"}
"""The package each format is written with (the `export` extra)."""

Progress = Callable[[str, int, int], None]
"""`progress(run_id, episodes done, episodes in all)`, called after each episode."""


@dataclass
class ExportSummary:
    """What an export wrote."""

    outputs: list[Path] = field(default_factory=list)
    """Per run: its log (inspect), or its folder of trajectories (atif)."""
    files: int = 0
    """Logs or trajectories written."""
    runs: int = 0
    episodes: int = 0
    steps: int = 0
    left_out: list[str] = field(default_factory=list)
    """One line for each view picture there but not exported (`Views.left_out`)."""


def check_choice(value: str, allowed: Sequence[str], option: str) -> None:
    if value not in allowed:
        raise replay.ConfigError(f"{option} must be one of {', '.join(allowed)}, not {value!r}")


def require(fmt: str) -> None:
    """The format's package, or one line saying how to install it (found, not imported:
    the Inspect writer needs none of inspect_ai's modules, only its dependencies)."""
    if importlib.util.find_spec(NEEDS[fmt]) is None:
        raise replay.ConfigError(
            f"--format {fmt} needs the {NEEDS[fmt]} package: pip install 'vge-analytics[export]'"
        )


def export(
    out: str | Path,
    fmt: str,
    dest: str | Path,
    *,
    runs: Sequence[str] | None = None,
    episodes: Sequence[str] | None = None,
    images: str = "embed",
    metrics_dir: str | Path | None = None,
    progress: Progress | None = None,
) -> ExportSummary:
    """Write the runs of OUT (all, or `runs`; their episodes, or `episodes` of them) to `dest`
    as Inspect logs (`fmt="inspect"`: `dest/<run_id>.eval`) or ATIF trajectories
    (`fmt="atif"`: `dest/<run_id>/<episode_id>.json`), with the views' pictures or not
    (`images`: `embed` or `none`). File names are made from ids by `replay.io.safe_file_name`."""
    check_choice(fmt, FORMATS, "--format")
    check_choice(images, IMAGES, "--images")
    require(fmt)
    source = open_source(out, runs=runs, episodes=episodes, metrics_dir=metrics_dir)
    root = Path(dest)
    root.mkdir(parents=True, exist_ok=True)
    summary = ExportSummary(runs=len(source.runs))
    counter = _Counter(source.episodes, progress)
    benches: dict[str, Views] = {}  # runs of one benchmark share its views and pictures
    for run in source.runs:
        views = benches.setdefault(str(run.bench), Views(run.bench))
        episodes_of = counter.count(run, source, summary)
        if fmt == "inspect":
            summary.outputs.append(
                _write_inspect(run, episodes_of, root, views, images, metrics_dir)
            )
            summary.files += 1
        else:
            folder, written = _write_atif(run, episodes_of, root, views, images)
            summary.outputs.append(folder)
            summary.files += written
    for views in benches.values():
        summary.left_out.extend(views.left_out())
    return summary


class _Counter:
    """Counts what goes by and reports it to `progress`."""

    def __init__(self, total: int, progress: Progress | None) -> None:
        self.total = total
        self.done = 0
        self.progress = progress

    def count(self, run: Run, source: Source, summary: ExportSummary) -> Iterator[Episode]:
        for episode in source.episodes_of(run):
            yield episode
            self.done += 1
            summary.episodes += 1
            summary.steps += len(episode.steps)
            if self.progress is not None:
                self.progress(run.run_id, self.done, self.total)


def _write_inspect(
    run: Run,
    episodes: Iterator[Episode],
    root: Path,
    views: Views,
    images: str,
    metrics_dir: str | Path | None,
) -> Path:
    from ._inspect import (
        LOG_VERSION,
        add_usage,
        eval_header,
        eval_plan,
        eval_results,
        eval_sample,
        eval_spec,
        eval_stats,
    )
    from ._inspect_log import write_eval

    pictures = views if images == "embed" else None
    usage: list[dict] = []  # the run's, summed as the samples go by

    def samples() -> Iterator[tuple[dict, int]]:
        for episode in episodes:
            sample, size = eval_sample(
                run, episode, views.names(episode.row["device_id"]), pictures
            )
            recorded = sample["model_usage"].get(run.model)
            if recorded is not None:
                usage.append(add_usage(usage.pop(), recorded) if usage else recorded)
            yield sample, size

    spec, plan = eval_spec(run, images), eval_plan(run)

    def finish() -> dict:
        results = eval_results(run, load_metrics(metrics_dir))
        return eval_header(spec, plan, results, eval_stats(run, usage[0] if usage else None))

    path = root / f"{replay.io.safe_file_name(run.run_id)}.eval"
    start = {"version": LOG_VERSION, "eval": spec, "plan": plan}
    with staged_path(path, sync=False) as staged:
        write_eval(staged, start, samples(), finish)
    return path


def _write_atif(
    run: Run, episodes: Iterator[Episode], root: Path, views: Views, images: str
) -> tuple[Path, int]:
    from ._atif import PictureFiles, trajectory, trajectory_json

    folder = make_folders(root, replay.io.safe_file_name(run.run_id))
    pictures = PictureFiles(folder, views) if images == "embed" else None
    written = 0
    for episode in episodes:
        traj = trajectory(run, episode, views.names(episode.row["device_id"]), pictures)
        path = folder / f"{replay.io.safe_file_name(episode.episode_id)}.json"
        write_atomic(path, trajectory_json(traj), sync=False)  # why not synced: replay.io
        written += 1
    return folder, written


__all__ = ["FORMATS", "IMAGES", "ExportSummary", "Progress", "export", "require"]
