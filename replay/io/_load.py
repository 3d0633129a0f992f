"""Reading inputs (PROTOCOL §1): SSM/UCSM files, tasks, run headers, episode logs; and the
validator behind `vge validate`. Every error names the file (and line). Inputs are local
paths or URIs (`_fs.location`). And the bytes of a run.json, beside its reader, for every
program that writes runs (`vge synth`, `vge run`, `vge play`)."""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import msgspec

from .._errors import InputError, Problem, SSMError, TaskError, VGEError, decode_error_message
from ..kernel import LogLine, decode_line
from ..semantics import (
    EpisodeLog,
    Machine,
    RunHeader,
    StateMachine,
    Task,
    compile_machine,
    meta_problem,
    setup_episode,
    validate_machine,
)
from ._decode import decode
from ._fs import Location, confined, confinement, location
from ._images import bench_image_problem
from ._layout import (
    EPISODES,
    EPISODES_FILES,
    EPISODES_GZ,
    SSM_DIR,
    SSM_SUFFIX,
    TASKS,
    UCSM_DIR,
    not_a_file_name,
    relative_inside,
    run_json_path,
    tasks_path,
)
from ._lines import MAX_RECORD_BYTES, iter_lines, read_whole

_BYTE = re.compile(r"byte (\d+)")
_ssm_decoder = msgspec.json.Decoder(StateMachine)
_task_decoder = msgspec.json.Decoder(Task)
_run_decoder = msgspec.json.Decoder(RunHeader)
episode_decoder = msgspec.json.Decoder(EpisodeLog)


def decode_episode_line(raw: bytes) -> EpisodeLog | LogLine:
    """A line of an episodes file for the kernel: decoded straight into its structs when
    `decode_line` can prove msgspec's reading (a `LogLine`), else by msgspec (`decode`, whose
    `msgspec.DecodeError` quarantines the line)."""
    line = decode_line(raw)
    return decode(episode_decoder, raw) if line is None else line


def episode_log(log: EpisodeLog | LogLine) -> EpisodeLog:
    """msgspec's log of a line `decode_episode_line` read, for what reads `LogStep`s (the
    reference replay): a `LogLine`'s line decoded again."""
    return decode(episode_decoder, log.raw) if type(log) is LogLine else log


def _line_of(data: bytes, message: str) -> int | None:
    m = _BYTE.search(message)
    if not m:
        return None
    return data.count(b"\n", 0, int(m.group(1))) + 1


def decode_state_machine(path: str | Path | Location) -> StateMachine:
    """Decode an SSM/UCSM JSON file (no semantic validation)."""
    path = location(path)
    data = read_whole(path)
    try:
        return decode(_ssm_decoder, data)
    except msgspec.DecodeError as exc:
        msg = decode_error_message(exc)
        raise InputError(str(path), msg, _line_of(data, msg)) from None


def load_ssm(path: str | Path | Location) -> StateMachine:
    """Decode and validate an SSM; raises `SSMError` listing every error, `InputError` on bad JSON."""
    ssm = decode_state_machine(path)
    errors = [p for p in validate_machine(ssm, str(path)) if p.severity == "error"]
    if errors:
        raise SSMError(errors)
    return ssm


def load_machine(path: str | Path | Location, device_id: str | None = None) -> Machine:
    """Decode, validate and compile an SSM file; the device id defaults to the file stem."""
    path = location(path)
    ssm = decode_state_machine(path)
    return compile_machine(ssm, device_id=device_id or path.stem, source=str(path))


MAX_RUN_JSON_BYTES = 1 << 20
"""The most bytes a run.json may take (PROTOCOL §1.5): a header, a bounded meta and room to
indent it; a wider one is refused before its meta is decoded."""


def read_run_header(run_dir: str | Path | Location) -> RunHeader:
    """run.json, decoded and checked: an empty run_id, or a meta too wide or with a number
    the tables cannot hold, is refused in one line naming the file (PROTOCOL §1.5)."""
    path = run_json_path(location(run_dir))
    data = read_whole(path, MAX_RUN_JSON_BYTES)
    try:
        header = decode(_run_decoder, data)
    except msgspec.DecodeError as exc:
        msg = decode_error_message(exc)
        raise InputError(str(path), msg, _line_of(data, msg)) from None
    if not header.run_id.strip():
        raise InputError(str(path), "run_id is empty")
    problem = meta_problem(header.meta)
    if problem is not None:
        raise InputError(str(path), problem)
    return header


def run_header_bytes(header: RunHeader | Mapping[str, Any]) -> bytes:
    """run.json's bytes: JSON indented by two spaces, with a final newline. A `RunHeader`'s
    fields come in their declared order and its meta's keys sorted; a mapping's keys in the
    order given."""
    order = "deterministic" if isinstance(header, RunHeader) else None
    return msgspec.json.format(msgspec.json.encode(header, order=order), indent=2) + b"\n"


def episodes_file(run_dir: str | Path | Location) -> Location:
    """`episodes.jsonl` or `episodes.jsonl.gz` of a run directory."""
    run_dir = location(run_dir)
    for name in EPISODES_FILES:
        candidate = run_dir / name
        if candidate.exists():
            return candidate
    raise InputError(str(run_dir / EPISODES), f"file not found (nor {EPISODES_GZ})")


@dataclass
class TaskEntry:
    task: Task
    line: int


@dataclass
class Benchmark:
    """A benchmark directory (PROTOCOL §1.1), loaded lazily: machines compile on first use."""

    root: Location
    tasks: dict[str, TaskEntry] = field(default_factory=dict)
    task_problems: list[Problem] = field(default_factory=list)
    ssm_paths: dict[str, Location] = field(default_factory=dict)
    outside: set[str] = field(default_factory=set)
    """Devices whose SSM file is a link out of BENCH (never read)."""
    _machines: dict[str, Machine | VGEError] = field(default_factory=dict, repr=False)

    @classmethod
    def open(cls, root: str | Path | Location) -> Benchmark:
        root = location(root)
        if not root.is_dir():
            raise InputError(str(root), "benchmark directory not found")
        ssm_dir = root / SSM_DIR
        if not ssm_dir.is_dir():
            raise InputError(str(ssm_dir), f"benchmark has no {SSM_DIR}/ directory")
        bench = cls(root=root)
        inside = confinement(root)
        for name in ssm_dir.names():
            if name.endswith(SSM_SUFFIX):
                path = ssm_dir / name
                if inside(path):
                    bench.ssm_paths[Path(name).stem] = path
                else:  # a link out of BENCH: never read, not even hashed
                    bench.outside.add(Path(name).stem)
        tasks = tasks_path(root)
        if not tasks.exists():
            raise InputError(str(tasks), "file not found")
        if not confined(root, tasks):
            raise InputError(str(tasks), "resolves outside the benchmark directory (a link)")
        for number, line in iter_lines(tasks):
            try:
                task = decode(_task_decoder, line)
            except msgspec.DecodeError as exc:
                bench.task_problems.append(
                    Problem(f"{tasks}:{number}", "", decode_error_message(exc))
                )
                continue
            if task.episode_id in bench.tasks:
                first = bench.tasks[task.episode_id].line
                bench.task_problems.append(
                    Problem(
                        f"{tasks}:{number}",
                        f"episode {task.episode_id!r}",
                        f"duplicate episode_id (first on line {first}); this line is ignored",
                    )
                )
                continue
            bench.tasks[task.episode_id] = TaskEntry(task, number)
        return bench

    @property
    def tasks_path(self) -> Location:
        return tasks_path(self.root)

    def no_machine(self, device_id: str) -> str | None:
        """Why a device has no SSM file to read (PROTOCOL §1.5), in words that follow its
        name; None when it has one. An id that cannot name a file is never made a path."""
        if device_id in self.ssm_paths:
            return None
        why = not_a_file_name(device_id)
        if why is not None:
            return f"cannot name an SSM file (it {why})"
        where = f"{SSM_DIR}/{device_id}{SSM_SUFFIX}"
        if device_id in self.outside:
            return f"has an SSM file {where} that links outside the benchmark directory"
        return f"has no SSM file {where}"

    def machine(self, device_id: str) -> Machine:
        """The compiled machine of a device; raises the (cached) load error."""
        got = self._machines.get(device_id)
        if got is None:
            path = self.ssm_paths.get(device_id)
            if path is None:
                got = InputError(str(self.root), f"device {device_id!r} {self.no_machine(device_id)}")
            else:
                try:
                    got = load_machine(path, device_id)
                except VGEError as exc:
                    got = exc
            self._machines[device_id] = got
        if isinstance(got, VGEError):
            raise got
        return got


def _problem(exc: InputError) -> Problem:
    return Problem(exc.path if exc.line is None else f"{exc.path}:{exc.line}", "", exc.message)


def validate_benchmark(root: str | Path | Location) -> list[Problem]:
    """Every problem of a benchmark: SSMs, UCSMs, tasks (PROTOCOL §1.1-1.3, 4)."""
    root = location(root)
    bench = Benchmark.open(root)
    problems: list[Problem] = []
    for device_id, path in bench.ssm_paths.items():
        problems.extend(_ssm_problems(root, device_id, path))
    for device_id in sorted(bench.outside):
        why = bench.no_machine(device_id)
        problems.append(Problem(str(root / SSM_DIR), f"device {device_id!r}", f"it {why}"))
    ucsm_dir = root / UCSM_DIR
    if ucsm_dir.is_dir():
        for path in [ucsm_dir / n for n in ucsm_dir.names() if n.endswith(SSM_SUFFIX)]:
            try:
                ucsm = decode_state_machine(path)
            except InputError as exc:
                problems.append(_problem(exc))
                continue
            problems.extend(validate_machine(ucsm, str(path), require_geometry=False))
    problems.extend(picture_problems(bench))
    problems.extend(bench.task_problems)
    for episode_id, entry in bench.tasks.items():
        problems.extend(_task_problems(bench, episode_id, entry))
    return problems


def picture_problems(bench: Benchmark, devices: Iterable[str] | None = None) -> list[Problem]:
    """A warning for each view whose picture file is there but not shown: too large, in bytes
    or pixels, or not a picture (§1.1); of the `devices` given (default: all). `vge validate`
    lists them, and the writers that show pictures (`vge replay --mcap`, `vge export`) say
    them too, as they leave those out."""
    problems = []
    chosen = bench.ssm_paths if devices is None else set(devices)
    for device_id in [d for d in bench.ssm_paths if d in chosen]:
        try:
            machine = bench.machine(device_id)
        except VGEError:
            continue  # an SSM that does not load is reported as such
        for view in machine.views:
            refused = bench_image_problem(bench.root, machine, view)
            if refused is not None:
                problems.append(Problem(refused.path, f"view {view}", refused.message, "warning"))
    return problems


def _ssm_problems(root: Location, device_id: str, path: Location) -> list[Problem]:
    """An SSM file's problems: its machine's, a `device_id` other than the file's name, a
    picture it names that is not there."""
    try:
        ssm = decode_state_machine(path)
    except InputError as exc:
        return [_problem(exc)]
    problems = validate_machine(ssm, str(path))
    if ssm.device_id is not None and ssm.device_id != device_id:
        problems.append(
            Problem(
                str(path),
                "device_id",
                f"device_id {ssm.device_id!r} differs from the file name; the file name is used",
                "warning",
            )
        )
    for view, ref in (ssm.images or {}).items():
        if not relative_inside(ref.path) or not confined(root, root / ref.path):
            problems.append(
                Problem(
                    str(path),
                    f"images.{view}",
                    f"image file {ref.path!r} is outside the benchmark directory; it is never read",
                )
            )
        elif not (root / ref.path).exists():
            problems.append(
                Problem(
                    str(path), f"images.{view}", f"image file {ref.path!r} not found", "warning"
                )
            )
    return problems


def _task_problems(bench: Benchmark, episode_id: str, entry: TaskEntry) -> list[Problem]:
    """A task's problems: its device, whether it can be played there, its instructions and
    its stated C_opt against the planner's."""
    where = f"{bench.tasks_path}:{entry.line}"
    episode = f"episode {episode_id!r}"
    task = entry.task
    device = task.device_id
    missing = bench.no_machine(device)
    if missing is not None:
        named = not_a_file_name(device) is None and device not in bench.outside
        said = f"unknown device {device!r}" if named else f"device {device!r} {missing}"
        return [Problem(where, episode, said)]
    try:
        machine = bench.machine(task.device_id)
    except VGEError:  # an SSM that does not decode or does not validate
        return [Problem(where, episode, f"device {task.device_id!r} has an invalid SSM")]
    try:
        setup = setup_episode(machine, task)
    except TaskError as exc:
        return [Problem(where, episode, str(exc).split(": ", 1)[-1])]
    problems = []
    if len(task.instructions) not in (0, len(task.goals)):
        problems.append(
            Problem(
                where,
                episode,
                f"{len(task.instructions)} instructions for {len(task.goals)} goals",
                "warning",
            )
        )
    stated = task.c_opt
    if stated is not None and list(stated) != list(setup.plan.c_opt):
        problems.append(
            Problem(
                where,
                episode,
                f"stated c_opt {list(stated)} differs from the computed {list(setup.plan.c_opt)}; the computed one is used",
                "warning",
            )
        )
    return problems


def validate_run(
    run_dir: str | Path | Location,
    bench: Benchmark,
    *,
    max_record_bytes: int = MAX_RECORD_BYTES,
) -> list[Problem]:
    """Problems of a run directory: header, episode lines (each at most `max_record_bytes`),
    unknown or duplicate episodes."""
    problems: list[Problem] = []
    run_dir = location(run_dir)
    try:
        read_run_header(run_dir)
    except InputError as exc:
        problems.append(_problem(exc))
    try:
        path = episodes_file(run_dir)
    except InputError as exc:
        problems.append(_problem(exc))
        return problems
    seen: dict[str, int] = {}
    try:
        for number, line in iter_lines(path, max_record_bytes=max_record_bytes):
            where = f"{path}:{number}"
            try:
                log = decode(episode_decoder, line)
            except msgspec.DecodeError as exc:
                problems.append(Problem(where, "", decode_error_message(exc)))
                continue
            if log.episode_id in seen:
                problems.append(
                    Problem(
                        where,
                        f"episode {log.episode_id!r}",
                        f"duplicate episode (first on line {seen[log.episode_id]})",
                    )
                )
                continue
            seen[log.episode_id] = number
            if log.episode_id not in bench.tasks:
                problems.append(
                    Problem(
                        where,
                        f"episode {log.episode_id!r}",
                        f"unknown episode id (not in {TASKS})",
                    )
                )
    except InputError as exc:
        problems.append(_problem(exc))
    return problems
