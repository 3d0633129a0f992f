"""Options several commands share, and the parsing of those that need it (`--where`,
`--episodes`)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, TypeVar

import typer

from replay import MAX_RECORD_BYTES, ConfigError

from .._errors import UnknownColumnError
from ..metrics import METRICS_DIR_ENV
from ..store import CLI_TIMEOUT
from ._output import FORMAT_HELP

R = TypeVar("R")

METRICS_DIR_HELP = (
    "A folder of metric files (.sql, in the format of the built-in metrics; see "
    "docs/METRICS.md): a file with a built-in's name overrides it, a new name adds a metric."
)


def metrics_dir_option(help: str = METRICS_DIR_HELP) -> str | None:
    """`--metrics-dir DIR`, defaulting to $VGE_METRICS_DIR (a typer option default)."""
    return typer.Option(None, "--metrics-dir", envvar=METRICS_DIR_ENV, show_envvar=True, help=help)


def out_argument() -> str:
    """OUT, the replay output directory the analytics read (a typer argument default)."""
    return typer.Argument(
        ..., help="Replay output directory (a path, or a URI such as s3://bucket/out)."
    )


def format_option() -> str:
    """`--format/-f`: how a table is printed (a typer option default)."""
    return typer.Option("table", "--format", "-f", help=FORMAT_HELP)


def by_option(default: str, help: str) -> str:
    """`--by COLUMN,...`: the grouping (a typer option default)."""
    return typer.Option(default, "--by", help=help)


def metric_names_option(help: str, default: str | None = None) -> str | None:
    """`--metrics NAME,...`: which metrics (a typer option default)."""
    return typer.Option(default, "--metrics", help=help)


def flag_option(name: str, help: str) -> bool:
    """A `--name` switch, off unless given (a typer option default)."""
    return typer.Option(False, name, help=help)


def where_option() -> list[str]:
    """`--where COLUMN=VALUE[,VALUE...]`, repeatable (a typer option default)."""
    return typer.Option(None, "--where", help="Filter COLUMN=VALUE[,VALUE...] (repeatable).")


def parse_where(items: list[str] | None) -> dict[str, list[str]]:
    """`--where col=v1,v2` options -> {col: [v1, v2]} (values cast to the column's type)."""
    where: dict[str, list[str]] = {}
    for item in items or []:
        col, sep, values = item.partition("=")
        if not sep or not col.strip():
            raise UnknownColumnError(f"--where expects COLUMN=VALUE[,VALUE...], got {item!r}")
        where.setdefault(col.strip(), []).extend(v.strip() for v in values.split(","))
    return where


def memory_limit_option(name: str = "--memory-limit", what: str = "the query") -> str | None:
    """A DuckDB memory limit, `512MB` or `4GB` (a typer option default)."""
    return typer.Option(
        None,
        name,
        help=f"Memory {what} may use, e.g. 512MB or 4GB (default: 512 MB plus half the size "
        "of OUT's tables, at most a quarter of this machine's memory); past it the query "
        "spills up to twice as much to a temporary directory, then stops.",
    )


def timeout_option() -> float:
    """`--timeout S`: how long each analytics query may run (a typer option default)."""
    return typer.Option(
        CLI_TIMEOUT,
        "--timeout",
        min=0.0,
        help="Seconds each query may run before it is stopped with one line (0: no limit); "
        "a metric file's expression that runs away ends there.",
    )


def max_record_bytes_option(outcome: str = "is quarantined as record_too_large") -> int:
    """`--max-record-bytes N` (a typer option default; `vge replay` and `vge validate`)."""
    return typer.Option(
        MAX_RECORD_BYTES,
        "--max-record-bytes",
        min=1,
        metavar="BYTES",
        help=f"The longest episode line read (64 MiB by default): a longer one {outcome} and "
        "the rest of its file is not read.",
    )


def ids_option(name: str, help: str) -> str | None:
    """`--runs` / `--episodes ID,...`: ids, comma-separated (a typer option default; parse it
    with `episode_ids`)."""
    return typer.Option(None, name, metavar="ID,...", help=help)


def episode_ids(text: str | None, option: str) -> tuple[str, ...] | None:
    """The episode ids of a comma-separated option (`--episodes`, `--mcap-episodes`); None
    when the option is not given, an error when it names none."""
    if text is None:
        return None
    ids = tuple(part.strip() for part in text.split(",") if part.strip())
    if not ids:
        raise ConfigError(f"{option}: no episode id given")
    return ids


def record_of(record: type[R], params: Mapping[str, Any], **given: Any) -> R:
    """A record of options (a msgspec struct) whose every field is the command's parameter of
    the same name, or in `given` (those the command parses or builds): the option names are
    then written once, in the command's signature, not again as `name=name` arguments. A field
    that is neither is an error of the code, not of the user."""
    fields = record.__struct_fields__
    missing = [f for f in fields if f not in given and f not in params]
    if missing:
        raise TypeError(f"{record.__name__}: no parameter for {', '.join(missing)}")
    return record(**{f: given[f] if f in given else params[f] for f in fields})


__all__ = [
    "METRICS_DIR_HELP",
    "by_option",
    "episode_ids",
    "flag_option",
    "format_option",
    "max_record_bytes_option",
    "ids_option",
    "memory_limit_option",
    "record_of",
    "metric_names_option",
    "metrics_dir_option",
    "out_argument",
    "parse_where",
    "timeout_option",
    "where_option",
]
