"""The layout of `replay/` shows its design: the readable rules (`semantics`) depend on
nothing else of the package, the compiled engine (`kernel`) on the rules only, input and
output (`io`) on both, the live environment (`env`) on all three; and the import chains stay
short."""

from __future__ import annotations

import ast
import functools
import re
from pathlib import Path

REPLAY = Path(__file__).resolve().parents[2] / "replay"
LAYERS = ("semantics", "kernel", "io", "env")
_PYX_IMPORT = re.compile(r"^from (\.+)([\w.]*) c?import", re.MULTILINE)


def _module(path: Path) -> str:
    parts = path.relative_to(REPLAY.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imported_names(tree: ast.AST, skip: frozenset[int] = frozenset()) -> list[tuple[int, str]]:
    """Every module a file names for import, as (level, name): relative and absolute
    imports, and the string given to `importlib.import_module` or `__import__` (a hidden
    import is still an arrow). Nodes whose id is in `skip` are left out."""
    found: list[tuple[int, str]] = []
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.ImportFrom):
            found.append((node.level, node.module or ""))
            if node.level == 0 and node.module:
                found.extend((0, f"{node.module}.{a.name}") for a in node.names)
        elif isinstance(node, ast.Import):
            found.extend((0, a.name) for a in node.names)
        elif isinstance(node, ast.Call) and node.args and isinstance(node.args[0], ast.Constant):
            func = node.func
            name = getattr(func, "attr", None) or getattr(func, "id", None)
            if name in ("import_module", "__import__") and isinstance(node.args[0].value, str):
                found.append((0, node.args[0].value))
    return found


def test_replay_never_names_the_analytics() -> None:
    """The lower room never imports the higher one, openly or through importlib: what the
    engine needs from the analytics (an image source, say) is passed in by the caller."""
    for path in [*REPLAY.rglob("*.py"), *REPLAY.rglob("*.pyx")]:
        text = path.read_text()
        if path.suffix == ".pyx":
            assert "vge_analytics" not in text, path
            continue
        for level, name in _imported_names(ast.parse(text)):
            assert not (level == 0 and name.split(".")[0] in ("vge_analytics", "app")), (
                f"{path.relative_to(REPLAY.parent)} imports {name}"
            )


def _runtime_imports(path: Path) -> set[str]:
    """Modules of `replay` imported at run time (not under `if TYPE_CHECKING:`), relative or
    absolute."""
    package = _module(path) if path.name == "__init__.py" else _module(path).rsplit(".", 1)[0]

    def resolve(level: int, name: str) -> str:
        base = package.split(".")
        base = base[: len(base) - level + 1]
        return ".".join(base + ([name] if name else []))

    text = path.read_text()
    if path.suffix == ".pyx":
        return {resolve(len(m.group(1)), m.group(2)) for m in _PYX_IMPORT.finditer(text)}
    tree = ast.parse(text)
    typing_only = frozenset(
        id(sub)
        for node in ast.walk(tree)
        if isinstance(node, ast.If) and getattr(node.test, "id", "") == "TYPE_CHECKING"
        for sub in ast.walk(node)
    )
    found = set()
    for level, name in _imported_names(tree, typing_only):
        if level:
            found.add(resolve(level, name))
        elif name.split(".")[0] == "replay":
            found.add(name)
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and id(node) not in typing_only and node.level:
            target = resolve(node.level, node.module or "")
            found.update(f"{target}.{a.name}" for a in node.names)
    return found


def _graph() -> dict[str, set[str]]:
    files = [*REPLAY.rglob("*.py"), *REPLAY.rglob("*.pyx")]
    modules = {_module(p): p for p in files}
    return {
        name: {m for m in _runtime_imports(path) if m in modules and m != name}
        for name, path in modules.items()
    }


def _layer(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 and parts[1] in LAYERS else "top"


def test_layers_depend_downwards_only() -> None:
    allowed = {
        "semantics": {"semantics", "top"},
        "kernel": {"kernel", "semantics", "top"},
        "io": {"io", "kernel", "semantics", "top"},
        "env": {"env", "io", "kernel", "semantics", "top"},
    }
    for module, deps in _graph().items():
        layer = _layer(module)
        if layer == "top":
            continue
        bad = {d for d in deps if _layer(d) not in allowed[layer] or d == "replay"}
        assert not bad, f"{module} imports {sorted(bad)}"


def test_import_chains_are_short() -> None:
    """The longest chain of imports between modules (an "import floor" per module); it was
    14 before the split into layers."""
    graph = _graph()
    packages = {_module(p) for p in REPLAY.rglob("__init__.py")}

    @functools.cache
    def floor(module: str) -> int:
        deps = [d for d in graph[module] if d not in packages and d != "replay"]
        return 1 + max((floor(d) for d in deps), default=0)

    floors = {m: floor(m) for m in graph if m not in packages}
    assert max(floors.values()) <= 9, sorted(floors.items(), key=lambda kv: -kv[1])[:5]
    assert max(v for m, v in floors.items() if _layer(m) == "semantics") <= 5


SHARED = frozenset({"replay._errors", "replay._lazy", "replay._version"})
"""The root's private modules every layer imports: the error classes, the lazy loading of a
package face's names and the engine version (leaves: they import nothing of the package)."""


def _private_imports(path: Path) -> list[str]:
    """Every private module a file of `replay` imports (at run time or for typing), by name
    or through `from package import _module`, as absolute names."""
    module = _module(path)
    package = module if path.name == "__init__.py" else module.rsplit(".", 1)[0]

    def resolve(level: int, name: str) -> str:
        if not level:
            return name
        base = package.split(".")
        return ".".join(base[: len(base) - level + 1] + ([name] if name else []))

    text = path.read_text()
    if path.suffix in (".pyx", ".pxd"):
        names = [resolve(len(m.group(1)), m.group(2)) for m in _PYX_IMPORT.finditer(text)]
    else:
        names = []
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.ImportFrom):
                target = resolve(node.level, node.module or "")
                names.append(target)
                names.extend(f"{target}.{a.name}" for a in node.names)
            elif isinstance(node, ast.Import):
                names.extend(a.name for a in node.names)
    return [n for n in names if n.split(".")[0] == "replay" and any(p.startswith("_") for p in n.split("."))]


def _owner(name: str) -> tuple[str, str]:
    """(the private module named, the package it belongs to): the name up to its first
    private part, and what comes before that part."""
    parts = name.split(".")
    first = next(i for i, p in enumerate(parts) if p.startswith("_"))
    return ".".join(parts[: first + 1]), ".".join(parts[:first])


def test_subpackages_import_each_other_through_their_public_names() -> None:
    """A module may import the private modules of its own subpackage; another subpackage
    (and the package's `__init__`) only through the names its `__init__` chooses. There
    were 62 imports of another layer's private modules (issue 24); now none."""
    found = []
    for path in [*REPLAY.rglob("*.py"), *REPLAY.rglob("*.pyx"), *REPLAY.rglob("*.pxd")]:
        module = _module(path)
        own = module if path.name == "__init__.py" else module.rsplit(".", 1)[0]
        for name in _private_imports(path):
            private, owner = _owner(name)
            if private in SHARED or owner == own:
                continue
            found.append(f"{path.relative_to(REPLAY.parent)} imports {name}")
    assert not found, "\n".join(found)


def test_each_subpackage_chooses_its_public_names() -> None:
    """Each layer opens with its purpose and lists its public names in `__all__`; each name
    listed is there (the package's own `__init__` too)."""
    import importlib

    for package in ("replay", *(f"replay.{layer}" for layer in LAYERS)):
        init = REPLAY.parent.joinpath(*package.split("."), "__init__.py")
        tree = ast.parse(init.read_text())
        assert ast.get_docstring(tree), f"{package} has no purpose line"
        loaded = importlib.import_module(package)
        assert loaded.__all__, package
        missing = [n for n in loaded.__all__ if not hasattr(loaded, n)]
        assert not missing, (package, missing)


def test_what_is_built_on_replay_names_its_public_modules_only() -> None:
    """The analytics, the app and the benchmarks import `replay` and its layers, never a
    private module of it (the tests may: they test the parts)."""
    found = []
    for folder in ("vge_analytics", "app", "benchmarks"):
        for path in sorted((REPLAY.parent / folder).rglob("*.py")):
            for level, name in _imported_names(ast.parse(path.read_text())):
                parts = name.split(".")
                if level == 0 and parts[0] == "replay" and any(p.startswith("_") for p in parts):
                    found.append(f"{path.relative_to(REPLAY.parent)} imports {name}")
    assert not found, "\n".join(found)
