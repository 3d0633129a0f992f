"""`vge` starts at once: importing the command line, registering every command and printing
any command's help import none of the heavy libraries (docs/PERFORMANCE.md, "Start-up").
Each command imports what it uses when it runs: `vge metrics OUT` answered by the metric
cache imports neither pyarrow's dataset module nor pandas (which it imports), and a question
asked before, answered by the answer kept, none of the heavy libraries. Measured in a fresh
interpreter (a test process has imported everything already); timings are in
benchmarks/bench_startup.py."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

from replay.io import METRIC_CACHE_DIR

HEAVY = (
    "numpy",
    "pandas",
    "pyarrow",
    "pyarrow.dataset",
    "pyarrow.compute",
    "duckdb",
    "polars",
    "ray",
    "streamlit",
    "inspect_ai",
    "replay.kernel",
    "pydantic",
)
"""What `vge --help` must not wait for (each costs a tenth of a second or more to import;
pydantic is what typer 0.29 checks every option with, pyproject.toml keeps typer below it)."""

PROBE = """
import json, sys
{body}
heavy = {heavy!r}
print(json.dumps(sorted({{h for m in sys.modules for h in heavy if m == h or m.startswith(h + ".")}})))
"""


def _imported(body: str) -> list[str]:
    """The heavy modules a fresh interpreter has imported after running `body`."""
    code = PROBE.format(body=body, heavy=HEAVY)
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True
    )
    return json.loads(done.stdout.splitlines()[-1])


def test_importing_the_command_line_imports_nothing_heavy() -> None:
    assert _imported("import vge_analytics.cli") == []


def test_every_commands_help_imports_nothing_heavy() -> None:
    body = """
import contextlib, io
from vge_analytics import cli
cli._register_all()
names = [c.name for c in cli.app.registered_commands]
assert len(names) >= 15, names
for args in ([], *([name] for name in names)):
    with contextlib.redirect_stdout(io.StringIO()):
        assert cli.main([*args, "--help"]) == 0, args
"""
    assert _imported(body) == []


def test_the_probe_sees_a_heavy_import() -> None:
    # The same probe, after the metrics are computed from a name: the libraries are there.
    assert _imported("import vge_analytics as va; va.metrics") == [
        "duckdb",
        "numpy",
        "polars",
        "pyarrow",
    ]


METRICS = """
import contextlib, io
from vge_analytics import cli
with contextlib.redirect_stdout(io.StringIO()):
    assert cli.main(["metrics", {out!r}, *{args!r}]) == 0
"""


def test_metrics_answered_by_the_cache_import_no_dataset_module(pair_out: Path, tmp_path: Path):
    """The first `vge metrics OUT` scans the tables (pyarrow's dataset module, and pandas,
    which it imports); a new question then reads the metric cache, and the runs table read
    whole; a question asked before prints the answer kept, and imports nothing heavy."""
    out = tmp_path / "out"
    shutil.copytree(pair_out, out, ignore=shutil.ignore_patterns(METRIC_CACHE_DIR))
    body = METRICS.format(out=str(out), args=["-f", "json"])
    cold = _imported(body)
    assert {"pandas", "pyarrow.dataset"} <= set(cold)
    assert _imported(body) == []
    for args in (["-f", "csv"], ["--by", "model"]):  # (the table format, for people)
        asked = METRICS.format(out=str(out), args=args)
        assert _imported(asked) == ["duckdb", "numpy", "polars", "pyarrow"]
        assert _imported(asked) == []
    # A metrics folder is told by its files' text: no DuckDB to check them again.
    folder = Path(__file__).parents[3] / "docs" / "examples" / "metrics"
    asked = METRICS.format(out=str(out), args=["--metrics-dir", str(folder), "-f", "latex"])
    assert {"duckdb", "polars"} <= set(_imported(asked))
    assert _imported(asked) == []


def test_a_command_that_reads_out_imports_no_dataset_module_before_its_first_file(
    tmp_path: Path,
):
    """The fixed cost of a command that reads OUT: its imports, then the one-line error of
    an OUT that does not exist."""
    body = f"""
import contextlib, io
from vge_analytics import cli
with contextlib.redirect_stderr(io.StringIO()):
    assert cli.main(["metrics", {str(tmp_path / "missing")!r}]) == 1
"""
    assert _imported(body) == ["duckdb", "numpy", "polars", "pyarrow"]
