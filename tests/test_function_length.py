"""No function or method is longer than a screen: at most 80 lines from its `def` to its
last line, docstring included, in replay/, vge_analytics/ and app/. Cython files are read as
text: a block opened by `def`, `cdef` or `cpdef` and a name with its arguments ends at the
next line indented no deeper.

`ALLOWED` names the exceptions, each with why; the list only shrinks."""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("replay", "vge_analytics", "app")
LIMIT = 80

ALLOWED: dict[str, str] = {}
"""`path::qualified name` -> why it may be longer. Data tables (a function that only states
a table) would be listed here too; there are none."""

_CYTHON_DEF = re.compile(r"^(\s*)c?p?def\s+(?:inline\s+)?(?:[\w*\[\]]+\s+)*?(\w+)\s*\(")
_CYTHON_CLASS = re.compile(r"^(\s*)(?:cdef\s+)?class\s+(\w+)")


def _python_functions(text: str) -> list[tuple[str, int]]:
    """(qualified name, lines) of every function and method."""
    found: list[tuple[str, int]] = []

    def visit(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                name = prefix + child.name
                found.append((name, child.end_lineno - child.lineno + 1))
                visit(child, name + ".")
            elif isinstance(child, ast.ClassDef):
                visit(child, prefix + child.name + ".")
            else:
                visit(child, prefix)

    visit(ast.parse(text), "")
    return found


def _cython_functions(text: str) -> list[tuple[str, int]]:
    """(qualified name, lines) of every `def`, `cdef` and `cpdef` function of a .pyx."""
    lines = text.splitlines()
    found: list[tuple[str, int]] = []
    classes: list[tuple[int, str]] = []  # (indent, name) of the classes around a line
    for i, line in enumerate(lines):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        indent = len(line) - len(line.lstrip())
        classes = [(d, c) for d, c in classes if d < indent]
        if (match := _CYTHON_CLASS.match(line)) and line.rstrip().endswith(":"):
            classes.append((indent, match.group(2)))
            continue
        match = _CYTHON_DEF.match(line)
        if match is None:
            continue
        last = i
        for j in range(i + 1, len(lines)):
            body = lines[j]
            if not body.strip() or body.lstrip().startswith("#"):
                continue
            if len(body) - len(body.lstrip()) <= indent and not body.lstrip().startswith(")"):
                break
            last = j
        prefix = "".join(f"{c}." for _, c in classes)
        found.append((prefix + match.group(2), last - i + 1))
    return found


def functions() -> dict[str, int]:
    """`path::qualified name` -> lines, for every function of the packages."""
    got: dict[str, int] = {}
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*")):
            if path.suffix == ".py":
                found = _python_functions(path.read_text())
            elif path.suffix == ".pyx":
                found = _cython_functions(path.read_text())
            else:
                continue
            rel = path.relative_to(ROOT).as_posix()
            for name, length in found:
                key = f"{rel}::{name}"
                got[key] = max(length, got.get(key, 0))
    return got


def test_no_function_is_longer_than_a_screen() -> None:
    long = {k: n for k, n in functions().items() if n > LIMIT and k not in ALLOWED}
    assert not long, "\n".join(f"{k}: {n} lines" for k, n in sorted(long.items()))


def test_the_allow_list_names_long_functions_that_exist() -> None:
    """An entry whose function got shorter (or went) leaves the list."""
    found = functions()
    stale = [k for k in ALLOWED if found.get(k, 0) <= LIMIT]
    assert not stale, f"no longer needed: {stale}"


def test_the_reader_measures_both_languages() -> None:
    """Worked by hand: a 3-line function and a method of a Cython class with a signature
    over two lines, a nested block and a comment at the margin inside it."""
    python = "class A:\n    def f(self):\n        x = 1\n        return x\n"
    assert _python_functions(python) == [("A.f", 3)]
    cython = (
        "cdef class K:\n"
        "    cdef int run(self,\n"
        "            int n) except -1:\n"
        "        if n:\n"
        "# a comment at the margin\n"
        "            return 1\n"
        "        return 0\n"
        "\n"
        "cdef inline double _d(const double* r) noexcept:\n"
        "    return r[0]\n"
        "cdef int[6] TABLE\n"
    )
    assert _cython_functions(cython) == [("K.run", 6), ("_d", 2)]
