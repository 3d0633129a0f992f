"""The `vge` command line: a thin router over the command modules.

Each command lives in `vge_analytics/commands/<name>.py` and exposes `register(app)`.
Errors derived from `replay.VGEError` become one-line messages (exit 1) unless `--debug`.

A command's module is imported when the command runs (`vge COMMAND ...` imports its own
alone; `vge --help` all of them), and is light: each imports what its command uses when it
runs, so `vge --help` and `vge COMMAND --help` start at once (docs/PERFORMANCE.md,
"Start-up"; `tests/vge_analytics/commands/test_startup.py` holds it).
"""

from __future__ import annotations

import importlib
import inspect
import sys
from pathlib import Path

import typer

from replay import VGEError

COMMANDS = (
    "demo",
    "validate",
    "replay",
    "synth",
    "run",
    "metrics",
    "errors",
    "compare",
    "power",
    "passk",
    "diff",
    "rescore",
    "sweep",
    "sql",
    "export",
    "app",
    "play",
)
"""The commands, in the order `vge --help` lists them: each is the module
`vge_analytics/commands/<name>.py`, whose `register(app)` adds it under that name."""

APP_SETTINGS: dict[str, object] = {
    "name": "vge",
    "help": "VGE Analytics: replay, score and explore VGEBench-style agent logs.",
    "no_args_is_help": True,
    "add_completion": False,
    "pretty_exceptions_enable": False,
}
"""How the `vge` app is made (`app`, and `_app_for` the app of one command)."""

app = typer.Typer(**APP_SETTINGS)

_state = {"debug": False}

OPTIONAL_VALUES = {"--ray": "auto"}
"""Options whose value may be left out (`--ray` alone means `--ray auto`)."""


def _fill_optional_values(args: list[str]) -> list[str]:
    """Insert the default value of an option given without one: at the end, before another
    option, or before an existing path (a run directory, not an address)."""
    out: list[str] = []
    for i, arg in enumerate(args):
        out.append(arg)
        default = OPTIONAL_VALUES.get(arg)
        if default is None:
            continue
        following = args[i + 1] if i + 1 < len(args) else None
        if following is None or following.startswith("-") or Path(following).exists():
            out.append(default)
    return out


@app.callback()
def _root(
    debug: bool = typer.Option(False, "--debug", help="Show full tracebacks on errors."),
) -> None:
    _state["debug"] = debug


def one_line(doc: str | None) -> str:
    """A command's description in `vge --help`: the first paragraph of its docstring, on one
    line (typer's rich help would keep the docstring's line breaks, cutting the sentence)."""
    return " ".join(inspect.cleandoc(doc or "").split("\n\n")[0].split())


def _register(typer_app: typer.Typer, names: tuple[str, ...]) -> None:
    """Add the commands `names` to `typer_app`, importing their modules."""
    for name in names:
        importlib.import_module(f"{__package__}.commands.{name}").register(typer_app)
    for info in typer_app.registered_commands:
        info.short_help = info.short_help or one_line(info.callback.__doc__)


def _register_all() -> None:
    if not app.registered_commands:
        _register(app, COMMANDS)


def _app_for(args: list[str]) -> typer.Typer:
    """The app that runs `args`: one holding only the command they name (their first word
    after the root's --debug), its module alone imported; the whole `app`, every command
    registered, when they name none (`vge --help`, `vge --help metrics`, a mistyped name,
    which click answers with the names it knows). Typer builds the options of every command
    an app holds before it runs one: a few hundredths of a second for all of them, and as
    much again to import their modules."""
    name = next((a for a in args if a != "--debug"), None)
    if name not in COMMANDS:
        _register_all()
        return app
    one = typer.Typer(**APP_SETTINGS)
    one.callback()(_root)
    _register(one, (name,))
    return one


def _usage_errors() -> tuple[type[Exception], ...]:
    """Click's exception classes: click's own, and those of the copy of click that typer
    0.2x carries (`typer.BadParameter` derives from its ClickException); a usage error of
    either is shown as click shows it, exit code 2."""
    import click

    vendored = [c for c in typer.BadParameter.__mro__ if c.__name__ == "ClickException"]
    return (click.ClickException, *vendored)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the `vge` console script."""
    args = _fill_optional_values(sys.argv[1:] if argv is None else list(argv))
    _state["debug"] = "--debug" in args
    try:
        result = _app_for(args)(args=args, standalone_mode=False)
    except VGEError as exc:
        if _state["debug"]:
            raise
        typer.echo(f"error: {exc}", err=True)
        return 1
    except typer.Exit as exc:
        return exc.exit_code
    except (typer.Abort, KeyboardInterrupt):
        typer.echo("aborted", err=True)
        return 130
    except Exception as exc:  # click usage errors and the like
        if isinstance(exc, _usage_errors()):
            exc.show()  # with click's "Possible options" for a near-miss (--metric)
            return exc.exit_code
        if _state["debug"]:
            raise
        typer.echo(f"error: {type(exc).__name__}: {exc} (run with --debug for details)", err=True)
        return 1
    # Without standalone mode, click returns the exit code of `typer.Exit` (or the command's
    # return value).
    return result if isinstance(result, int) else 0


if __name__ == "__main__":
    sys.exit(main())
