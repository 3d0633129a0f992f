"""A package's public names, imported when first used.

A package face (`replay`, `replay.io`, and the faces of packages built on replay) names what it offers
with ordinary imports written under `if TYPE_CHECKING:`, so that tools (type checkers,
linters, the layering tests, a reader) see every name and where it comes from, and ends with

    __getattr__, __dir__ = lazy_names(__name__, __file__)

Nothing is imported with the package: the first time a name is asked for, its module is
(and whatever that module imports), and the name is kept in the package's namespace. So
`vge --help` does not pay for DuckDB, pandas or the compiled kernel, and each command imports
what it uses (docs/PERFORMANCE.md, "Start-up"). A name that is not in the block but is a
subpackage or module of the package is imported as such (`replay.io`). A name in the block
keeps its meaning when a submodule of the same name is imported, as with eager imports: a
function `pkg.name` stays the function when a module `pkg.name` is imported too.
"""

from __future__ import annotations

import ast
import importlib
import importlib.util
import sys
import types
from collections.abc import Callable
from pathlib import Path


def _names_of(init_file: str) -> dict[str, tuple[str, str]]:
    """{name: (relative module, name in it, "" for the module itself)} of the `from ... import ...` statements under
    `if TYPE_CHECKING:` at the top level of a package's `__init__.py`."""
    tree = ast.parse(Path(init_file).read_text(encoding="utf-8"))
    found: dict[str, tuple[str, str]] = {}
    for node in tree.body:
        test = node.test if isinstance(node, ast.If) else None
        if not (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING"):
            continue
        for statement in node.body:  # type: ignore[attr-defined]
            if isinstance(statement, ast.ImportFrom):
                module = "." * statement.level + (statement.module or "")
                for alias in statement.names:
                    if statement.module is None:  # `from . import module`
                        found[alias.asname or alias.name] = (module + alias.name, "")
                    else:
                        found[alias.asname or alias.name] = (module, alias.name)
    return found


class _Face(types.ModuleType):
    """A package whose public names win over its submodules of the same name: the import
    system records a submodule on its package when it is imported, which would hide a
    public name still to be imported (`lazy_names`)."""

    _lazy_table: Callable[[], dict[str, tuple[str, str]]]

    def __setattr__(self, name: str, value: object) -> None:
        if (
            isinstance(value, types.ModuleType)
            and value.__name__ == f"{self.__name__}.{name}"
            and self._lazy_table().get(name, ("", ""))[1]  # the name is not the module's
        ):
            return
        super().__setattr__(name, value)


def lazy_names(
    package: str, init_file: str
) -> tuple[Callable[[str], object], Callable[[], list[str]]]:
    """The `__getattr__` and `__dir__` of a package whose public names are imported under
    `if TYPE_CHECKING:` in its `init_file`."""
    table: dict[str, tuple[str, str]] = {}

    def names() -> dict[str, tuple[str, str]]:
        if not table:
            table.update(_names_of(init_file))
        return table

    face = sys.modules[package]
    face._lazy_table = names  # type: ignore[attr-defined]
    face.__class__ = _Face

    def __getattr__(name: str) -> object:  # noqa: N807 - the module hook's name
        entry = names().get(name)
        if entry is None:
            if not name.startswith("__") and importlib.util.find_spec(f"{package}.{name}"):
                return importlib.import_module(f"{package}.{name}")
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        module, attribute = entry
        imported = importlib.import_module(module, package)
        value = getattr(imported, attribute) if attribute else imported
        setattr(sys.modules[package], name, value)  # asked once
        return value

    def __dir__() -> list[str]:  # noqa: N807 - the module hook's name
        return sorted(set(vars(sys.modules[package])) | set(names()))

    return __getattr__, __dir__


__all__ = ["lazy_names"]
