"""Every error the engine raises, in one hierarchy.

The CLI turns any `VGEError` into a one-line message naming the file (and line) involved.
"""

from __future__ import annotations


class VGEError(Exception):
    """Base class of every error the project raises on purpose."""


class InputError(VGEError):
    """A problem with an input file: names the file and, where known, the line."""

    def __init__(self, path: str, message: str, line: int | None = None) -> None:
        self.path = str(path)
        self.line = line
        self.message = message
        where = f"{self.path}:{line}" if line is not None else self.path
        super().__init__(f"{where}: {message}")


class OutputError(VGEError):
    """A file that could not be written (a full disk, a quota, a file-size limit): names the
    output file, never the input being read when it happened."""

    def __init__(self, path: str, message: str) -> None:
        self.path = str(path)
        self.message = message
        super().__init__(f"{self.path}: {message}")


class RecordTooLarge(InputError):
    """A record (a line, or a run of blank lines) longer than the maximum size of a record:
    the reading of its file stops there (PROTOCOL §1.5)."""


class PictureError(InputError):
    """A view picture that is not decoded: not a PNG, JPEG or WebP picture, or larger than a
    view picture may be, in bytes or in pixels (PROTOCOL §1.1). It counts as absent."""


class Problem(VGEError):
    """One validation problem; `where` locates it (file, state, component...)."""

    def __init__(self, path: str, where: str, message: str, severity: str = "error") -> None:
        self.path = str(path)
        self.where = where
        self.message = message
        self.severity = severity
        loc = f"{self.path} [{where}]" if where else self.path
        super().__init__(f"{loc}: {message}")


class SSMError(VGEError):
    """A state machine failed validation; carries every problem found, not just the first."""

    def __init__(self, problems: list[Problem]) -> None:
        self.problems = problems
        first = problems[0] if problems else None
        more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
        super().__init__(f"{first}{more}" if first else "invalid state machine")


class TaskError(VGEError):
    """A task cannot be played on its device (bad goals, unplannable, bad view)."""


class ConfigError(VGEError):
    """Bad options or arguments (unknown metric, bad lambda, missing directory...)."""


class ActionError(VGEError):
    """An action given to the live environment is neither text nor a structured action
    `{"type", "coord", "params"}` (PROTOCOL §1.4)."""


class WorkerError(VGEError):
    """A replay worker process died (killed, out of memory, or a script without a
    `if __name__ == "__main__":` guard started `replay_runs(workers > 1)`)."""


def decode_error_message(exc: Exception) -> str:
    """msgspec's message, made readable: 'Expected `str`, got `int` - at `$.goals[0]`'."""
    return str(exc).replace("`", "")
