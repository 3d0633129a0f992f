"""Kept answers: what `vge metrics OUT` printed, kept beside OUT, so that the same question
asked again is answered before pyarrow, polars or DuckDB is imported (docs/METRICS.md, The
metric cache; docs/PERFORMANCE.md, Start-up).

What the command prints (its warning lines on stderr, its table on stdout) is decided by
OUT's contents, the question (every option as given, the metrics' definitions), the code that
computes and prints it, and, for the table format, the console it is printed on. The first
time a question is asked it is answered as always (`store`, `reports`), printed, and kept in
`OUT/.metric-cache/answer-<contents>-<question>.json` (`replay.io.answer_cache_path`):
`<contents>` is the key of OUT's contents the rest of the folder uses
(`store.local_contents`: the manifest's sha256, the size and modification time of every
table file), `<question>` a hash of the rest (`question_key`). Asked again, the file is found
from those two keys and printed through the same door (`Printed.show`): byte for byte what
was printed the first time.

Bounded and safe as the rest of the folder: nothing is kept for an OUT in object storage,
without a manifest, or whose folder is a link (`store.own_folder`); a file is written whole
or not at all, and only when OUT's contents were the same before and after the answer was
computed; an answer over `MAX_ANSWER_BYTES` is not kept; keeping one removes the answers
kept for other contents of OUT and the oldest past `MAX_ANSWERS`. A file that is not a
regular file, too large, not the expected JSON or of another format is not read: the
question is answered again.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

import replay
from replay.io import answer_cache_path, atomic_file

from ..store import code_key, prune_kept, read_kept
from ._output import Printed, console_traits

ANSWER_FORMAT = 1
"""The version of an answer file's layout (a new one names other files)."""

MAX_ANSWER_BYTES = 1 << 20
"""The largest answer kept (its file's size): a table of a row per run is kilobytes."""

MAX_ANSWERS = 64
"""Answers kept per OUT: past it, keeping one removes the oldest."""


@dataclass(frozen=True, slots=True)
class Answer:
    """What a command printed: its warning lines (stderr), then its output (stdout)."""

    warnings: tuple[str, ...]
    printed: Printed

    def show(self, warn: Callable[[str], None]) -> None:
        for line in self.warnings:
            warn(line)
        self.printed.show()

    def encoded(self) -> bytes:
        doc = {
            "format": ANSWER_FORMAT,
            "warnings": list(self.warnings),
            "text": self.printed.text,
            "console": self.printed.console,
        }
        return json.dumps(doc, ensure_ascii=False).encode()


def _decoded(data: bytes) -> Answer | None:
    """The answer a file holds, or None when it is not one."""
    try:
        doc = json.loads(data.decode())
    except (ValueError, RecursionError):  # not UTF-8, not JSON, nested past Python's stack
        return None
    if not isinstance(doc, dict) or set(doc) != {"format", "warnings", "text", "console"}:
        return None
    warnings, text, console = doc["warnings"], doc["text"], doc["console"]
    if (
        doc["format"] != ANSWER_FORMAT
        or not isinstance(warnings, list)
        or not all(isinstance(w, str) for w in warnings)
        or not isinstance(text, str)
        or not isinstance(console, bool)
    ):
        return None
    return Answer(tuple(warnings), Printed(text, console=console))


def question_key(command: str, options: Mapping[str, object], definitions: str) -> str:
    """A hash of the question: the command, its options as given, the metrics' definitions
    (`metrics.folder_fingerprint`: the metric files of a folder, or the built-ins alone,
    which are files of the package), the code, and the console a table is printed on
    (`console_traits`)."""
    doc = {
        "command": command,
        "options": dict(options),
        "metrics": definitions,
        "code": code_key(),
        "console": console_traits() if options.get("fmt") == "table" else None,
    }
    text = json.dumps(doc, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:32]


@dataclass(frozen=True, slots=True)
class Question:
    """Where the answer to a question about a local OUT is kept: the key of OUT's contents
    it was asked of, its own key, and how to tell that key again (`asked`)."""

    out: Path
    contents: str
    key: str
    path: Path
    asked: Callable[[], str | None]

    def answer(self) -> Answer | None:
        """The answer kept, or None."""
        data = read_kept(self.path, MAX_ANSWER_BYTES)
        return None if data is None else _decoded(data)

    def keep(self, answer: Answer) -> None:
        """Keep `answer` when OUT's contents, and the question, are still those it was asked
        of: no file of OUT or of the metrics changed while it was computed (nothing when OUT
        cannot be written, or the answer is too large)."""
        from ..store import local_contents, own_folder

        data = answer.encoded()
        if len(data) > MAX_ANSWER_BYTES or local_contents(self.out) != self.contents:
            return
        if self.asked() != self.key or not own_folder(self.out):
            return
        with contextlib.suppress(OSError, replay.VGEError):
            self.path.parent.mkdir(exist_ok=True)
            with atomic_file(self.path, sync=False) as fh:
                fh.write(data)
            prune_kept(self.path, "answer-*.json", MAX_ANSWERS)


def question(
    out: str,
    command: str,
    options: Mapping[str, object],
    definitions: Callable[[], str | None],
) -> Question | None:
    """The question `options` asks `command` of a local OUT with a manifest, `definitions`
    telling the metrics' (`metrics.folder_fingerprint`), or None: an OUT in object storage
    or without a manifest, or whose `METRIC_CACHE_DIR` is a link, or metrics that cannot be
    told without loading them."""
    from ..store import local_contents, own_folder

    if replay.is_uri(out):
        return None
    path = Path(out)
    if not path.is_dir() or not own_folder(path):
        return None

    def asked() -> str | None:
        told = definitions()
        return None if told is None else question_key(command, options, told)

    contents, key = local_contents(path), asked()
    if contents is None or key is None:
        return None
    return Question(path, contents, key, answer_cache_path(path, contents, key), asked)


__all__ = [
    "ANSWER_FORMAT",
    "MAX_ANSWERS",
    "MAX_ANSWER_BYTES",
    "Answer",
    "Question",
    "question",
    "question_key",
]
