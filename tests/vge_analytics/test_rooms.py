"""`vge_analytics` is in rooms that say what they are (docs/ARCHITECTURE.md): each opens with
its purpose, the rooms import one another only along the arrows below and only through a
room's public names, the package keeps at most ten top-level modules and no source file
passes 700 lines. The import reader is the replay layering test's: relative and absolute
imports, and importlib strings."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from ..replay.test_layout import _imported_names

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "vge_analytics"
ROOMS = ("store", "metrics", "reports", "dashboard", "synth", "live", "play", "export", "commands")
ARROWS: dict[str, set[str]] = {
    "store": set(),
    "metrics": {"store"},
    "reports": {"metrics", "store"},
    # the synthetic benchmark's summaries are the registry's metrics (synth.measure_output)
    "synth": {"metrics", "reports", "store"},
    "live": {"synth"},
    "play": {"synth"},
    "dashboard": {"store", "metrics", "reports", "synth"},
    "export": {"store", "metrics", "reports", "synth", "live"},
    "commands": set(ROOMS) - {"commands"},
}
"""Which rooms each room may import (besides `replay`, `_errors` and the package's public
names); the arrows go one way, from the products down to the store."""


def _room(path: Path) -> str | None:
    parts = path.relative_to(PACKAGE).parts
    return parts[0] if len(parts) > 1 else None


def _targets(path: Path) -> list[tuple[str, str | None]]:
    """(room imported, its module if a private one is named) for every import of a file."""
    package = ".".join(path.relative_to(ROOT).with_suffix("").parts[:-1])
    found = []
    for level, name in _imported_names(ast.parse(path.read_text())):
        if level:
            base = package.split(".")
            base = base[: len(base) - level + 1]
            name = ".".join([*base, name] if name else base)
        parts = name.split(".")
        if parts[0] != "vge_analytics" or len(parts) < 2 or parts[1] not in ROOMS:
            continue
        found.append((parts[1], parts[2] if len(parts) > 2 and parts[2].startswith("_") else None))
    return found


SOURCES = sorted(p for p in PACKAGE.rglob("*.py"))


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: str(p.relative_to(PACKAGE)))
def test_rooms_import_each_other_along_the_arrows_through_public_names(path: Path) -> None:
    mine = _room(path)
    for room, private in _targets(path):
        if room == mine:
            continue
        where = path.relative_to(ROOT)
        if mine is not None:
            assert room in ARROWS[mine], f"{where}: {mine} may not import {room}"
        assert private is None, f"{where} reaches into {room}.{private}; import {room}'s public names"


def test_each_room_says_what_it_is_and_chooses_its_public_names() -> None:
    for room in ROOMS:
        if room == "commands":  # the CLI reaches each command module's `register`
            assert ast.get_docstring(ast.parse((PACKAGE / room / "__init__.py").read_text()))
            continue
        init = PACKAGE / room / "__init__.py"
        tree = ast.parse(init.read_text())
        assert ast.get_docstring(tree), f"{room}/__init__.py has no purpose line"
        targets = [t for n in tree.body if isinstance(n, ast.Assign) for t in n.targets]
        names = {e.id for t in targets for e in getattr(t, "elts", [t]) if isinstance(e, ast.Name)}
        assert "__all__" in names, f"{room}/__init__.py chooses no public names"


def test_the_package_keeps_few_top_level_modules_and_short_files() -> None:
    top = sorted(p.name for p in PACKAGE.glob("*.py"))
    assert len(top) <= 10, top
    for path in [*PACKAGE.rglob("*.py"), *(ROOT / "replay").rglob("*.py"), *(ROOT / "app").rglob("*.py")]:
        lines = path.read_text().count("\n")
        assert lines <= 700, f"{path.relative_to(ROOT)}: {lines} lines"


def test_only_the_commands_start_the_app_through_its_public_names() -> None:
    """The app is above the analytics: only the commands that serve it name it, through what
    its `__init__` offers (`app.ENTRY_FILE`, `app.warm`), never a module of it or a string."""
    starters = {PACKAGE / "commands" / "app.py", PACKAGE / "commands" / "_serve.py"}
    for path in SOURCES:
        tree = ast.parse(path.read_text())
        named = [name for level, name in _imported_names(tree) if not level]
        apps = [n for n in named if n == "app" or n.startswith("app.")]
        where = path.relative_to(ROOT)
        if path not in starters:
            assert not apps, f"{where} imports {apps}"
            continue
        assert apps == ["app"], f"{where} imports {apps}"
        used = {
            n.attr
            for n in ast.walk(tree)
            if isinstance(n, ast.Attribute) and isinstance(n.value, ast.Name)
            and n.value.id in ("app", "dashboard_app")
        }
        assert used <= {"ENTRY_FILE", "warm"}, f"{where} uses app.{used}"
