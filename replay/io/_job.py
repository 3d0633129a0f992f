"""The job, one run as the main process of `vge replay` sees it: its lines read in batches
(`_reading.LineReader`), one `BatchTask` per batch, the batch reports taken in line order
(duplicates decided here, where every line of the run is seen in order), quarantine records
written, counts added up; then the staged parts are committed into OUT
(`OUT/.replay/staging/<run_id>/` -> `OUT/<table>/run_id=<run_id>/`, `_files.commit_dir`)
and the run's manifest entry made."""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Callable, Iterator

from .._errors import InputError, OutputError, RecordTooLarge
from .._version import ENGINE_VERSION
from ..semantics import arrow_schema
from ._batch import (
    BatchCounts,
    BatchFailure,
    BatchReport,
    BatchTask,
    RunContext,
)
from ._file_names import mcap_file_name, part_name
from ._files import STATE_DIR, commit_dir, remove_dir, write_part
from ._fs import Location
from ._images import ImageSource
from ._layout import (
    EPISODES_TABLE,
    GOALS_TABLE,
    MCAP_DIR,
    QUARANTINE,
    STEPS_TABLE,
    listed_mcap,
    listed_part,
    mcap_dir,
    partition_dir,
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
from ._quarantine import QuarantineRecord, encode_record
from ._reading import LineReader, RunInput
from ._rows import TABLE_ROWS

BATCH_LINES = 4096
"""Episode lines per batch: the unit of work of a worker and of a Parquet part (fixed,
whatever the workers)."""
BATCH_BYTES = 32 << 20
"""A batch ends early once its lines hold this many bytes, so the batches read ahead and in
flight stay bounded in memory however long the lines are. Twice the largest batch of the
full synthetic benchmark (15 MB): its batches, and the sample's, are cut by lines only."""
DIVERGENCE_FIELDS = ("feedback", "state", "view")
QUARANTINE_SPOOL = 8 << 20
"""Bytes of a run's quarantine records kept in memory before they spill to a temporary file."""


class RunJob:
    """Replays one run into a staging directory, then swaps it into OUT: `batches()` are
    its tasks, `take` accounts for each report in order, `finish_reading` and `commit` end
    it (`entry` is then its manifest entry), `abort` drops it."""

    reader: LineReader
    entry: RunEntry

    def __init__(
        self,
        run: RunInput,
        bench: Benchmark,
        bench_given: str,
        out: Location,
        options: RunOptions,
        image_source: ImageSource | None,
        row_group_rows: int,
    ) -> None:
        self.run = run
        self.bench = bench
        self.bench_given = bench_given
        self.out = out
        self.options = options
        self.state_dir = out / STATE_DIR
        self.staging = self.state_dir / "staging" / run.header.run_id
        self.staging.rmtree()
        for name in TABLE_ROWS:
            (self.staging / name).mkdir()
        if options.mcap:
            (self.staging / MCAP_DIR).mkdir()
        h = run.header
        self.ctx = RunContext(
            run_id=h.run_id,
            model=h.model,
            agent_kind=h.agent_kind,
            run_lambda=h.lam,
            option_lambda=options.lam,
            file=str(run.episodes),
            staging=str(self.staging),
            row_group_rows=row_group_rows,
            mcap=options.mcap,
            mcap_episodes=(
                None if options.mcap_episodes is None else frozenset(options.mcap_episodes)
            ),
            image_source=image_source,
            prices=run.prices,
        )
        self.parts: dict[str, list[str]] = {name: [] for name in TABLE_ROWS}
        self.seen: dict[str, int] = {}
        self.devices: dict[str, None] = {}
        self.lines_read = 0
        self.replayed = 0
        self.counts = BatchCounts()
        self.by_kind: dict[str, int] = {}
        # the run's records, moved to OUT/.replay/quarantine/<run_id>.jsonl at the commit
        self._quarantine = tempfile.SpooledTemporaryFile(QUARANTINE_SPOOL)  # noqa: SIM115

    def batches(self) -> Iterator[BatchTask]:
        """The run's lines, read in batches of `BATCH_LINES` (or fewer: `BATCH_BYTES`), as
        tasks for `replay_batch`."""
        self.reader = LineReader(
            self.run.episodes, BATCH_LINES, BATCH_BYTES, self.options.max_record_bytes
        )
        for index, lines in enumerate(self.reader.batches()):
            yield BatchTask(self.ctx, self.bench_given, index, tuple(lines))

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
        self.by_kind[kind] = self.by_kind.get(kind, 0) + 1

    def take(
        self,
        task: BatchTask,
        result: BatchReport | BatchFailure,
        redo: Callable[[BatchTask], BatchReport | BatchFailure],
    ) -> int:
        """Account for one batch, in line order; returns the lines it held.

        A line repeating an episode id seen earlier in the run is a duplicate. The worker
        cannot know that (it sees one batch), so a batch holding a replayed duplicate is
        replayed again (`redo`, rare) with those lines skipped, which rewrites its parts."""
        result = self._checked(result)
        duplicates = self._duplicates(result)
        if not duplicates.keys() <= {o.line for o in result.others}:  # one was replayed
            first_try = result
            result = self._checked(redo(task.skipping(frozenset(duplicates))))
            for line in duplicates.keys() & first_try.mcap.keys():
                (self.staging / MCAP_DIR / first_try.mcap[line][1]).unlink(missing_ok=True)
        self.lines_read += result.lines
        self.replayed += result.lines - len(result.others)
        self.devices.update(dict.fromkeys(result.devices))
        for o in result.others:
            if o.line in duplicates:
                episode_id, first = duplicates[o.line]
                self.quarantine(
                    o.line,
                    episode_id,
                    "duplicate_episode",
                    f"episode {episode_id!r} already appeared on line {first}; "
                    "only the first occurrence is replayed",
                )
            else:
                self.quarantine(o.line, o.episode_id, o.kind, o.reason or "")
        self._publish_mcaps(result)
        self.counts.add(result.counts)
        for name, rows in result.parts.items():
            if rows:
                self.parts[name].append(part_name(task.index))
        return result.lines

    def _duplicates(self, result: BatchReport) -> dict[int, tuple[str, int]]:
        """The batch's lines whose episode id an earlier line of the run had (line -> the
        id, the line that first had it); the ids first seen here are marked seen."""
        seen = self.seen
        return {
            line: (eid, first)
            for eid, line in zip(result.episode_ids, result.episode_lines, strict=True)
            if (first := seen.setdefault(eid, line)) != line
        }

    def _publish_mcaps(self, result: BatchReport) -> None:
        """The MCAP files of the replayed lines, renamed from their temporary names."""
        mcap = self.staging / MCAP_DIR
        for episode_id, mcap_tmp in result.mcap.values():
            self.counts.mcap_files += 1
            (mcap / mcap_tmp).replace(mcap / mcap_file_name(episode_id))

    def _checked(self, result: BatchReport | BatchFailure) -> BatchReport:
        if isinstance(result, BatchFailure):
            if result.output is not None:
                raise OutputError(result.output, result.message)
            raise InputError(self.ctx.file, result.message, result.line) from RuntimeError(
                result.details
            )
        return result

    def finish_reading(self) -> None:
        """What ends a file early is one record: `record_too_large` at the line too long,
        or `truncated_file` at the first line that could not be read."""
        last_line, error = self.reader.last_line, self.reader.error
        if error is None:
            return
        self.lines_read += 1
        if isinstance(error, RecordTooLarge):
            self.quarantine(error.line or last_line + 1, None, "record_too_large", error.message)
            return
        self.quarantine(
            last_line + 1,
            None,
            "truncated_file",
            f"the file cannot be read from line {last_line + 1} on: {error.message}",
        )

    def abort(self) -> None:
        self._quarantine.close()
        self.staging.rmtree()

    def _listed(self, table: str) -> list[str]:
        """The run's parts of a table as the manifest lists them, sorted."""
        return [listed_part(table, self.ctx.run_id, f) for f in sorted(self.parts[table])]

    def stage(self, inputs: RunInputs) -> tuple[RunEntry, Location]:
        """Finish the run's files in staging (an empty part for a table with none, its
        quarantine records): its manifest entry (also kept as `entry`) and where its
        quarantine records are staged. Nothing in OUT changes yet."""
        for name, row_type in TABLE_ROWS.items():
            if not self.parts[name]:  # every run has at least one (empty) part per table
                table = arrow_schema(row_type).empty_table()
                write_part(table, self.staging / name / part_name(0), self.ctx.row_group_rows)
                self.parts[name].append(part_name(0))
        staged = self.staging / QUARANTINE
        self._quarantine.seek(0)
        with staged.writer() as fh:
            shutil.copyfileobj(self._quarantine, fh)
        self._quarantine.close()
        self.entry = self._entry(inputs)
        return self.entry, staged

    def swap_in(self) -> None:
        """Move the staged run into OUT: its partitions, its MCAP folder, its quarantine
        records (renames on disk, `commit_dir`)."""
        run_id = self.ctx.run_id
        trash = self.state_dir / "trash"
        for name in TABLE_ROWS:
            commit_dir(self.staging / name, partition_dir(self.out, name, run_id), trash)
        if self.options.mcap:
            commit_dir(self.staging / MCAP_DIR, mcap_dir(self.out, run_id), trash)
        else:
            remove_dir(mcap_dir(self.out, run_id), trash)
        qdir = self.state_dir / "quarantine"
        qdir.mkdir()
        (self.staging / QUARANTINE).replace(qdir / f"{run_id}.jsonl")
        self.staging.rmtree()

    def _entry(self, inputs: RunInputs) -> RunEntry:
        run_id = self.ctx.run_id
        c = self.counts
        h = self.run.header
        return RunEntry(
            run_id=run_id,
            engine_version=ENGINE_VERSION,
            inputs=inputs,
            options=self.options,
            run=RunInfo(model=h.model, agent_kind=h.agent_kind, lam=h.lam, meta=h.meta),
            counts=RunCounts(
                lines_read=self.lines_read,
                replayed=self.replayed,
                quarantined=sum(self.by_kind.values()),
                steps=c.steps,
                truncated_steps=c.truncated,
                diverged_steps=c.diverged,
                goals=c.goals,
                mcap_files=c.mcap_files,
            ),
            quarantine=dict(sorted(self.by_kind.items())),
            divergence=Divergence(
                steps_compared=c.compared,
                steps_diverged=c.diverged,
                episodes_diverged=c.episodes_diverged,
                by_field={f: c.by_field.get(f, 0) for f in DIVERGENCE_FIELDS},
            ),
            outputs=RunOutputs(
                steps=self._listed(STEPS_TABLE),
                episodes=self._listed(EPISODES_TABLE),
                goals=self._listed(GOALS_TABLE),
                mcap=listed_mcap(run_id) if self.options.mcap else None,
            ),
        )
