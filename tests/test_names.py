"""Every name has one home (docs/ARCHITECTURE.md, "Where each name lives"): the protocol's
vocabularies (terminations, feedback kinds, views, action names, the pseudo-components, the
words of the parameter codes) in `replay/semantics/_vocab.py`, the on-disk layout (file,
folder, table and partition names) in `replay/io/_layout.py`, and `vge synth`'s own folders in
`vge_analytics/synth/_build.py`. A search of replay/, vge_analytics/ and app/ for those names
as string constants (the Python sources through their syntax trees, the Cython kernel as
text) finds them in their homes, where a rule below says they mean something else, and in
the short allow-list; anywhere else the test fails and names the file and line.

The names are read from the homes themselves, so a new termination or a new file name is
checked the day it is added.
"""

from __future__ import annotations

import ast
import re
import typing
from pathlib import Path

import msgspec
import pytest

import replay.semantics as sem
from replay.env import STEP_FIELDS
from replay.io import _layout as layout
from replay.io import _manifest
from replay.semantics import _records, _rows
from vge_analytics import synth
from vge_analytics.metrics._file import Grain

ROOT = Path(__file__).resolve().parents[1]
TREES = ("replay", "vge_analytics", "app")

# ------------------------------------------------------------------ the names and their homes

VOCAB_HOME = "replay/semantics/_vocab.py"
LAYOUT_HOME = "replay/io/_layout.py"
SYNTH_HOME = "vge_analytics/synth/_build.py"

_codes = {m for meanings in sem.PARAMETER_CODES.values() for m in meanings}
VOCABULARY: dict[str, str] = {
    **{n: "termination" for n in sem.TERMINATIONS},
    **{n: "feedback kind" for n in sem.FEEDBACK_KINDS},
    **{n: "view" for n in sem.VIEWS},
    **{n: "action" for n in sem.ACTION_NAMES},
    **{n: "action" for n in sem.DISPLAY_NAMES.values()},
    **{n: "pseudo-component" for n in sem.PSEUDO_COMPONENTS},
    # the words of the codes; `up` and `down` are too common to be the codes' alone
    **{m: "parameter code" for m in _codes if m not in sem.VIEW_RANK and len(m) > 4},
}
"""Protocol names, checked wherever a string stands (PROTOCOL §2, §3)."""

FILES: dict[str, str] = {
    n: "file"
    for n in (
        layout.TASKS,
        layout.RUN_JSON,
        layout.EPISODES,
        layout.EPISODES_GZ,
        layout.FAILURES,
        layout.RUNS_FILE,
        layout.QUARANTINE,
        layout.MANIFEST,
        synth.SUMMARY,
    )
}
TABLES: dict[str, str] = {n: "table" for n in layout.TABLES}
FOLDERS: dict[str, str] = {
    n: "folder"
    for n in (
        layout.SSM_DIR,
        layout.UCSM_DIR,
        layout.IMAGES_DIR,
        layout.MCAP_DIR,
        synth.BENCH_DIR,
        synth.RUNS_DIR,
        *layout.TABLES,
    )
}
"""Folder names are also the names of schemas (`ssm`), of record fields (`images`) and of
options (`mcap`): they are checked where they build a path (a `/` operand, or a piece of a
path such as `"ssm/"` or `"runs/runs.parquet"`)."""
PARTITION = f"{layout.PARTITION_KEY}="
CHECKED = {*VOCABULARY, *FILES, *TABLES}

HOMES: dict[str, set[str]] = {
    VOCAB_HOME: set(VOCABULARY),
    "replay/semantics/_endings.py": set(sem.TERMINATIONS),  # the words of each termination
    LAYOUT_HOME: {*FILES, *TABLES, *FOLDERS} - {synth.SUMMARY, synth.BENCH_DIR},
    SYNTH_HOME: {synth.SUMMARY, synth.BENCH_DIR, synth.RUNS_DIR},
}


def _fields() -> set[str]:
    names = set(STEP_FIELDS)
    for module in (_records, _rows, _manifest):
        for value in vars(module).values():
            if isinstance(value, type) and issubclass(value, msgspec.Struct):
                names.update(value.__struct_fields__)
    return names | {f.name for f in _manifest._RUN_COLUMNS}


FIELDS = _fields()
"""Fields of the records and columns of the tables (PROTOCOL §1, §7): `success`,
`budget_global`, `dashboard_unlocked`, `steps`, `episodes`, `goals`, ... are also the names of
a field, and where a field stands (a dict key, a subscript, the argument of `.get`, `pl.col`,
`pa.field`, a `columns=` argument, or a tuple of keys) they are that field, whose home is its
record."""

LIBRARY_WORDS = {
    "how",  # polars' joins: "left"
    "justify",  # rich: "left", "right"
    "title_justify",
    "side",  # numpy.searchsorted: "right"
    "orient",  # altair's legends: "bottom", "top"
    "titleOrient",
    "align",  # altair's text: "left"
    "vertical_alignment",  # streamlit's columns: "bottom"
    "maintain_order",  # polars: "left"
}
"""Keyword arguments whose values are a library's own words, which happen to be views."""

ALLOWED: dict[tuple[str, str], str] = {
    ("replay/semantics/_records.py", "front"): "the task's default initial view, in its record "
    "declaration (the JSON Schema shows it); the vocabulary sits below the rule modules, not "
    "the records",
    ("vge_analytics/export/_inspect.py", "success"): "Inspect's status of a finished log",
    ("vge_analytics/play/_page.py", "success"): "Streamlit's `st.success`, the tone of info",
    ("vge_analytics/synth/_thinking.py", "left"): "where a part sits in the picture, in the "
    "simulated agent's words",
    ("vge_analytics/synth/_thinking.py", "right"): "likewise",
    ("vge_analytics/synth/_thinking.py", "steps"): "the plural of a rotation's step, likewise",
    (VOCAB_HOME, "steps"): "what the prompt calls Rotate's second parameter (its notches)",
    ("vge_analytics/dashboard/_leaderboard.py", "episodes"): "the cost table's count column, "
    "named as the runs table names its count",
    ("vge_analytics/reports/inference/_repeated.py", "success"): "the episodes table's success "
    "column, the values pivoted per run",
}
"""Where a name may stand outside its home, and why. Keep it short."""


# ------------------------------------------------------------------ reading the sources


def _documentation(tree: ast.AST) -> set[int]:
    """Ids of the string constants that are documentation: docstrings, and strings standing
    alone as statements (a field's or a constant's docstring)."""
    return {
        id(node.value)
        for node in ast.walk(tree)
        if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant)
    }


def _exempt(tree: ast.AST) -> tuple[set[int], set[int], set[int]]:
    """(identifiers and library words, field positions, path positions) by constant id."""
    identifiers: set[int] = set()
    fields: set[int] = set()
    paths: set[int] = set()

    def constants(node: ast.AST) -> list[ast.Constant]:
        return [n for n in ast.walk(node) if isinstance(n, ast.Constant)]

    for node in ast.walk(tree):
        names = isinstance(node, ast.Assign) and any(
            isinstance(t, ast.Name) and t.id in ("__all__", "__slots__") for t in node.targets
        )
        if names or (isinstance(node, ast.keyword) and node.arg in LIBRARY_WORDS):
            identifiers.update(map(id, constants(node.value)))  # identifiers, a library's words
        elif isinstance(node, ast.keyword) and node.arg == "columns":
            fields.update(map(id, constants(node.value)))
        elif (
            isinstance(node, ast.Subscript)
            and isinstance(node.value, ast.Name | ast.Attribute)
            and (node.value.id if isinstance(node.value, ast.Name) else node.value.attr)
            == "Literal"
        ):
            identifiers.update(map(id, constants(node.slice)))  # a type spells its values
        elif isinstance(node, ast.Dict):
            fields.update(id(k) for k in node.keys if isinstance(k, ast.Constant))
        elif isinstance(node, ast.Subscript) and isinstance(node.slice, ast.Constant):
            fields.add(id(node.slice))
        elif (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Attribute)
            and node.func.attr in ("get", "col", "field", "pop", "setdefault", "alias")
        ):
            fields.update(id(a) for a in node.args[:1] if isinstance(a, ast.Constant))
        elif isinstance(node, ast.Tuple | ast.List):
            strings = [e.value for e in node.elts if isinstance(e, ast.Constant)]
            if _keys(strings):
                fields.update(id(e) for e in node.elts if isinstance(e, ast.Constant))
        elif isinstance(node, ast.BinOp) and isinstance(node.op, ast.Div):
            paths.update(id(n) for n in (node.left, node.right) if isinstance(n, ast.Constant))
    return identifiers, fields, paths


def _keys(strings: list) -> bool:
    """A tuple or list of keys: its strings are field names or unchecked words, one at least
    a field that is no protocol name (`("success", "spl")`, not `("steps", "goals")`)."""
    if not all(isinstance(s, str) for s in strings):
        return False
    return all(s in FIELDS or s not in CHECKED for s in strings) and any(
        s in FIELDS and s not in CHECKED for s in strings
    )


def _path_piece(text: str) -> list[str]:
    """The segments of a constant that is a piece of a path (`ssm/`, `/manifest.json`,
    `runs/runs.parquet`, `steps/run_id=`), else nothing: prose has spaces."""
    if "/" not in text or any(c.isspace() for c in text):
        return []
    return [s for s in text.split("/") if s]


def findings(path: Path, source: str) -> list[tuple[int, str, str]]:
    """(line, name, what) of every name outside its home in one Python source."""
    rel = path.relative_to(ROOT).as_posix()
    home = HOMES.get(rel, set())
    tree = ast.parse(source)
    documentation = _documentation(tree)
    identifiers, fields, paths = _exempt(tree)
    found = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.Constant) or not isinstance(node.value, str):
            continue
        if id(node) in documentation or id(node) in identifiers:
            continue
        text = node.value
        names = []
        if text in VOCABULARY:
            names.append((text, VOCABULARY[text]))
        if text in FILES:
            names.append((text, FILES[text]))
        if text in TABLES:
            names.append((text, TABLES[text]))
        if text in FOLDERS and id(node) in paths:
            names.append((text, FOLDERS[text]))
        if text.startswith(PARTITION) or text == PARTITION:
            names.append((PARTITION, "partition"))
        for piece in _path_piece(text):
            if piece in FOLDERS or piece in FILES:
                names.append((piece, "path"))
            elif piece.startswith(PARTITION):
                names.append((PARTITION, "partition"))
        for name, what in names:
            if name in home or (rel, name) in ALLOWED:
                continue
            if name in FIELDS and id(node) in fields:
                continue
            found.append((node.lineno, name, what))
    return sorted(set(found))


def _sources() -> list[Path]:
    return sorted(p for tree in TREES for p in (ROOT / tree).rglob("*.py"))


@pytest.mark.parametrize("path", _sources(), ids=lambda p: p.relative_to(ROOT).as_posix())
def test_names_live_in_their_homes(path: Path) -> None:
    found = findings(path, path.read_text(encoding="utf-8"))
    rel = path.relative_to(ROOT).as_posix()
    assert not found, "\n".join(
        f"{rel}:{line}: the {what} name {name!r} is spelled outside its home "
        "(use the constant of replay.semantics, replay.io or vge_analytics.synth)"
        for line, name, what in found
    )


_QUOTED = re.compile(r"\"([^\"\s]+)\"")


def test_the_kernel_spells_no_name() -> None:
    """The Cython kernel, read as text: a quoted name is a column (a field) or nothing."""
    found = []
    for path in sorted((ROOT / "replay" / "kernel").glob("*.pyx")):
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            for word in _QUOTED.findall(line.split("#")[0]):
                if word in FIELDS:
                    continue  # the kernel's output columns
                if word in VOCABULARY or word in FILES or word in TABLES:
                    found.append(f"{path.name}:{number}: {word!r}")
    assert not found, found


def test_the_allow_list_is_short_and_used() -> None:
    assert len(ALLOWED) <= 9
    for (rel, name), why in ALLOWED.items():
        assert why
        text = (ROOT / rel).read_text(encoding="utf-8")
        assert f'"{name}"' in text, f"{rel} no longer spells {name!r}: drop it from ALLOWED"


def test_literal_types_match_their_homes() -> None:
    """A `Literal` type spells its values (type checkers need them); each such type of a
    vocabulary equals its home's list."""
    assert typing.get_args(Grain) == layout.GRAINS
    ended = typing.get_type_hints(_records.EpisodeLog)["ended"]
    assert typing.get_args(typing.get_args(ended)[0]) == (sem.CONTEXT_EXCEEDED,)


@pytest.mark.parametrize(
    ("source", "expected"),
    [
        ('x = "budget_local"', [(1, "budget_local", "termination")]),
        ('TRUNCATED = ("budget_global", "budget_local")', [(1, "budget_global", "termination"),
                                                           (1, "budget_local", "termination")]),
        ('ok = row["success"] and pl.col("budget_global")', []),  # fields
        ('COLUMNS = ("success", "spl")', []),  # a list of columns
        ('path = out / "ssm" / name', [(1, "ssm", "folder")]),
        ('SCHEMAS = {"ssm": 1}', []),  # a schema's name, not a folder
        ('f = f"{out}/manifest.json"', [(1, "manifest.json", "path")]),
        ('p = f"steps/run_id={r}"', [(1, "run_id=", "partition"), (1, "steps", "path")]),
        ('m = "see OUT/manifest.json for more"', []),  # prose
        ('t.join(u, how="left")', []),
        ('"""The front view."""', []),
        ('a = Action("press", None, ())', [(1, "press", "action")]),
        ('k = "a short press"', [(1, "a short press", "parameter code")]),
    ],
)
def test_the_search_itself(source: str, expected: list) -> None:
    """What the search flags and what it leaves, on small sources worked by hand."""
    assert findings(ROOT / "vge_analytics" / "example.py", source) == sorted(expected)
