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


def _runtime_imports(path: Path) -> set[str]:
    """Modules of `replay` imported at run time (not under `if TYPE_CHECKING:`)."""
    package = _module(path) if path.name == "__init__.py" else _module(path).rsplit(".", 1)[0]

    def resolve(level: int, name: str) -> str:
        base = package.split(".")
        base = base[: len(base) - level + 1]
        return ".".join(base + ([name] if name else []))

    text = path.read_text()
    if path.suffix == ".pyx":
        return {resolve(len(m.group(1)), m.group(2)) for m in _PYX_IMPORT.finditer(text)}
    tree = ast.parse(text)
    typing_only = {
        id(sub)
        for node in ast.walk(tree)
        if isinstance(node, ast.If) and getattr(node.test, "id", "") == "TYPE_CHECKING"
        for sub in ast.walk(node)
    }
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and id(node) not in typing_only and node.level:
            target = resolve(node.level, node.module or "")
            found.add(target)
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
