"""One run replayed into a staging directory (`OUT/.replay/staging/<run_id>/`), then swapped
into OUT: batch results are accounted for (duplicates decided here, where every line of the run
is seen in order), quarantined records written, rows written in batch order, counts tallied."""

from __future__ import annotations

import os
import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO

import pyarrow as pa
import pyarrow.compute as pc

from .._errors import InputError
from .._version import ENGINE_VERSION
from ..semantics._tables import TABLE_ROWS, arrow_schema
from ._batch import (
    BatchFailure,
    BatchResult,
    RunContext,
    safe_file_name,
)
from ._load import Benchmark
from ._manifest import (
    Divergence,
    RunCounts,
    RunEntry,
    RunInfo,
    RunInputs,
    RunOptions,
    RunOutputs,
)
from ._mcap import ImageSource
from ._quarantine import QuarantineRecord, encode_record
from ._reading import LineReader, RunInput
from ._writer import PartWriter, remove_dir, swap_in

CHUNK_LINES = 64
"""Rows reach the Parquet writer in Arrow chunks of this many episode lines: a column's page
layout depends on chunk boundaries, so cutting them by lines (counted from the start of the
file) keeps the files independent of the batch size and the number of workers."""
STATE_DIR = ".replay"
"""Private state under OUT: per-run quarantine records, the lock, staging and trash."""
DIVERGENCE_FIELDS = ("feedback", "state", "view")


@dataclass
class Tally:
    """Counts of one run, from the batch outcomes and the (kept) rows."""

    lines_read: int = 0
    replayed: int = 0
    steps: int = 0
    truncated: int = 0
    diverged: int = 0
    compared: int = 0
    episodes_diverged: int = 0
    goals: int = 0
    mcap_files: int = 0
    by_field: dict[str, int] = field(default_factory=lambda: dict.fromkeys(DIVERGENCE_FIELDS, 0))
    by_kind: dict[str, int] = field(default_factory=dict)

    def add_tables(self, steps: pa.Table, episodes: pa.Table, goals: pa.Table) -> None:
        self.steps += steps.num_rows
        self.goals += goals.num_rows
        if steps.num_rows:
            self.truncated += pc.sum(steps["truncated"]).as_py() or 0
            diverged = steps["diverged"]
            self.compared += len(diverged) - diverged.null_count
            self.diverged += pc.sum(diverged).as_py() or 0
            flat = pc.list_flatten(steps["diverged_fields"])
            if len(flat):
                for item in pc.value_counts(flat).to_pylist():
                    name = item["values"]
                    self.by_field[name] = self.by_field.get(name, 0) + item["counts"]
        if episodes.num_rows:
            self.episodes_diverged += pc.sum(pc.greater(episodes["diverged_steps"], 0)).as_py() or 0


class ChunkWriter:
    """Hands a table's rows to its PartWriter in chunks of CHUNK_LINES episode lines (one
    Arrow chunk each, whatever the batches the rows came in)."""

    def __init__(self, writer: PartWriter) -> None:
        self.writer = writer
        self.open: int | None = None  # the chunk being gathered
        self.pieces: list[pa.Table] = []

    def add(self, table: pa.Table, rows: list[tuple[int, int]]) -> None:
        """`table` holds, in order, `n` rows of chunk `c` for each (c, n) of `rows`."""
        at = 0
        for chunk, n in rows:
            if chunk != self.open:
                self._flush()
                self.open = chunk
            if n:
                self.pieces.append(table.slice(at, n))
                at += n

    def flush_complete(self, first_open: int | None) -> None:
        """Write the gathered chunk if it is before chunk `first_open` (None: in any case)."""
        if self.open is not None and (first_open is None or self.open < first_open):
            self._flush()

    def _flush(self) -> None:
        if self.pieces:
            table = self.pieces[0] if len(self.pieces) == 1 else pa.concat_tables(self.pieces)
            self.writer.write(table.combine_chunks())
        self.pieces = []
        self.open = None


def keep_mask(n: int, drops: list[tuple[int, int]]) -> pa.Array:
    keep = [True] * n
    for start, count in drops:
        keep[start : start + count] = [False] * count
    return pa.array(keep, pa.bool_())


class RunJob:
    """Replays one run into a staging directory, then swaps it into OUT."""

    def __init__(
        self,
        run: RunInput,
        bench: Benchmark,
        out: Path,
        options: RunOptions,
        image_source: ImageSource | None,
        library: str,
    ) -> None:
        self.run = run
        self.bench = bench
        self.out = out
        self.options = options
        self.state_dir = out / STATE_DIR
        self.staging = self.state_dir / "staging" / run.header.run_id
        if self.staging.exists():
            shutil.rmtree(self.staging)
        self.staging.mkdir(parents=True)
        self.mcap_dir = self.staging / "mcap" if options.mcap else None
        if self.mcap_dir is not None:
            self.mcap_dir.mkdir()
        h = run.header
        self.ctx = RunContext(
            run_id=h.run_id,
            model=h.model,
            agent_kind=h.agent_kind,
            run_lambda=h.lam,
            option_lambda=options.lam,
            file=str(run.episodes),
            mcap_dir=None if self.mcap_dir is None else str(self.mcap_dir),
            mcap_episodes=(
                None if options.mcap_episodes is None else frozenset(options.mcap_episodes)
            ),
            image_source=image_source,
            library=library,
        )
        self.writers = {
            name: PartWriter(self.staging / name, arrow_schema(row_type))
            for name, row_type in TABLE_ROWS.items()
        }
        self.chunks = {name: ChunkWriter(w) for name, w in self.writers.items()}
        self.seen: dict[str, int] = {}
        self.items = 0  # episode lines taken so far (blank lines are not items)
        self.devices: dict[str, None] = {}
        self.tally = Tally()
        self._quarantine_path = self.staging / "quarantine.jsonl"
        self._quarantine: BinaryIO = open(self._quarantine_path, "wb")  # noqa: SIM115

    def quarantine(self, line: int, episode_id: str | None, kind: str, reason: str) -> None:
        record = QuarantineRecord(
            run_id=self.ctx.run_id,
            file=self.ctx.file,
            line=line,
            episode_id=episode_id,
            kind=kind,
            reason=reason,
        )
        self._quarantine.write(encode_record(record))
        self.tally.by_kind[kind] = self.tally.by_kind.get(kind, 0) + 1

    def take(self, result: BatchResult | BatchFailure) -> int:
        """Account for one batch result and write its rows; returns the lines it held."""
        if isinstance(result, BatchFailure):
            raise InputError(self.ctx.file, result.message, result.line) from RuntimeError(
                result.details
            )
        tally = self.tally
        drops: list[tuple[int, int]] = []
        step_drops: list[tuple[int, int]] = []
        goal_drops: list[tuple[int, int]] = []
        episode_pos = step_pos = goal_pos = 0
        chunks: dict[int, list[int]] = {}  # chunk -> [steps, episodes, goals] rows kept
        for j, o in enumerate(result.outcomes):
            tally.lines_read += 1
            rows = chunks.setdefault((self.items + j) // CHUNK_LINES, [0, 0, 0])
            kind, reason = o.kind, o.reason
            if o.decoded and o.episode_id is not None:
                first = self.seen.get(o.episode_id)
                if first is not None:
                    kind = "duplicate_episode"
                    reason = (
                        f"episode {o.episode_id!r} already appeared on line {first}; "
                        "only the first occurrence is replayed"
                    )
                else:
                    self.seen[o.episode_id] = o.line
                    entry = self.bench.tasks.get(o.episode_id)
                    if entry is not None:
                        self.devices.setdefault(entry.task.device_id)
            if o.kind is None:  # replayed by the worker
                if kind is None:
                    tally.replayed += 1
                    rows[0] += o.n_steps
                    rows[1] += 1
                    rows[2] += o.n_goals
                    if o.mcap_tmp is not None:
                        self._publish_mcap(o.mcap_tmp, o.episode_id)
                else:  # a duplicate: drop its rows
                    drops.append((episode_pos, 1))
                    step_drops.append((step_pos, o.n_steps))
                    goal_drops.append((goal_pos, o.n_goals))
                    if o.mcap_tmp is not None and self.mcap_dir is not None:
                        (self.mcap_dir / o.mcap_tmp).unlink(missing_ok=True)
                episode_pos += 1
                step_pos += o.n_steps
                goal_pos += o.n_goals
            if kind is not None:
                self.quarantine(o.line, o.episode_id, kind, reason or "")
        steps, episodes, goals = result.steps, result.episodes, result.goals
        if drops:
            steps = steps.filter(keep_mask(steps.num_rows, step_drops))
            episodes = episodes.filter(keep_mask(episodes.num_rows, drops))
            goals = goals.filter(keep_mask(goals.num_rows, goal_drops))
        tally.add_tables(steps, episodes, goals)
        self.items += len(result.outcomes)
        for k, (name, table) in enumerate(
            (("steps", steps), ("episodes", episodes), ("goals", goals))
        ):
            self.chunks[name].add(table, [(c, rows[k]) for c, rows in chunks.items()])
            self.chunks[name].flush_complete(self.items // CHUNK_LINES)
        return len(result.outcomes)

    def _publish_mcap(self, tmp_name: str, episode_id: str | None) -> None:
        assert self.mcap_dir is not None and episode_id is not None
        os.replace(self.mcap_dir / tmp_name, self.mcap_dir / f"{safe_file_name(episode_id)}.mcap")
        self.tally.mcap_files += 1

    def finish_reading(self, reader: LineReader) -> None:
        if reader.error is not None:
            self.tally.lines_read += 1
            self.quarantine(
                reader.last_line + 1,
                None,
                "truncated_file",
                f"the file cannot be read from line {reader.last_line + 1} on: "
                f"{reader.error.message}",
            )

    def abort(self) -> None:
        for writer in self.writers.values():
            writer.abort()
        self._quarantine.close()
        shutil.rmtree(self.staging, ignore_errors=True)

    def commit(self, inputs: RunInputs) -> RunEntry:
        """Close the staged files and swap the run's partitions into OUT."""
        for chunks in self.chunks.values():
            chunks.flush_complete(None)
        files = {name: w.close() for name, w in self.writers.items()}
        self._quarantine.close()
        run_id = self.ctx.run_id
        trash = self.state_dir / "trash"
        for name in TABLE_ROWS:
            swap_in(self.staging / name, self.out / name / f"run_id={run_id}", trash)
        if self.mcap_dir is not None:
            swap_in(self.mcap_dir, self.out / "mcap" / run_id, trash)
        else:
            remove_dir(self.out / "mcap" / run_id, trash)
        qdir = self.state_dir / "quarantine"
        qdir.mkdir(parents=True, exist_ok=True)
        os.replace(self._quarantine_path, qdir / f"{run_id}.jsonl")
        shutil.rmtree(self.staging, ignore_errors=True)
        t = self.tally
        h = self.run.header
        return RunEntry(
            run_id=run_id,
            engine_version=ENGINE_VERSION,
            inputs=inputs,
            options=self.options,
            run=RunInfo(model=h.model, agent_kind=h.agent_kind, lam=h.lam, meta=h.meta),
            counts=RunCounts(
                lines_read=t.lines_read,
                replayed=t.replayed,
                quarantined=sum(t.by_kind.values()),
                steps=t.steps,
                truncated_steps=t.truncated,
                diverged_steps=t.diverged,
                goals=t.goals,
                mcap_files=t.mcap_files,
            ),
            quarantine=dict(sorted(t.by_kind.items())),
            divergence=Divergence(
                steps_compared=t.compared,
                steps_diverged=t.diverged,
                episodes_diverged=t.episodes_diverged,
                by_field=dict(sorted(t.by_field.items())),
            ),
            outputs=RunOutputs(
                steps=[f"steps/run_id={run_id}/{f}" for f in files["steps"]],
                episodes=[f"episodes/run_id={run_id}/{f}" for f in files["episodes"]],
                goals=[f"goals/run_id={run_id}/{f}" for f in files["goals"]],
                mcap=None if self.mcap_dir is None else f"mcap/{run_id}",
            ),
        )
