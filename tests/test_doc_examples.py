"""The docs' examples run as written from a fresh clone (tests/doc_examples.py says how a
block is marked runnable and what is checked): each doc with runnable blocks, in a copy of
the repository, its blocks in order; every command exits as the doc says, prints what the
doc shows, and writes nothing outside gitignored folders. The finder and the checks
themselves are tested on a small document first."""

from __future__ import annotations

from pathlib import Path

import pytest

from .doc_examples import ROOT, blocks, environment, problems, run_block, run_doc, runnable_docs

SMALL = '''# A doc

```bash
echo not runnable
```

```bash runnable
mkdir -p runs && echo one > runs/a.txt
```

```console runnable
$ X=$(echo two)
$ echo "$X" \\
  three
two three
$ cat runs/a.txt; exit 3   # exit 3
one
$ echo "$X"
```
'''


def test_the_runnable_blocks_and_their_commands(tmp_path: Path) -> None:
    doc = tmp_path / "DOC.md"
    doc.write_text(SMALL)
    found = blocks(doc)
    assert [(b.kind, b.line) for b in found] == [("bash", 7), ("console", 11)]
    commands = found[1].commands
    assert [c.text for c in commands] == [
        "X=$(echo two)",
        'echo "$X" \\\n  three',
        "cat runs/a.txt; exit 3   # exit 3",
        'echo "$X"',
    ]
    assert [c.expected for c in commands] == [None, ["two three"], ["one"], None]
    assert [c.exit_code for c in commands] == [0, 0, 3, 0]


def test_runs_compare_and_report(tmp_path: Path) -> None:
    doc = tmp_path / "DOC.md"
    doc.write_text(SMALL)
    bash, console = blocks(doc)
    env = environment(tmp_path / "cache")
    assert problems(bash, run_block(bash, tmp_path, env)) == []
    # `exit 3` ends the shell: the last command never runs, and that is said.
    results = run_block(console, tmp_path, env)
    assert [(r.exit_code, r.output) for r in results] == [(0, []), (0, ["two three"]), (3, ["one"])]
    assert problems(console, results) == ["DOC.md:11: the block stopped after 3 command(s)"]
    # Output and exit codes other than the doc's are named.
    doc.write_text(SMALL.replace("two three\n", "two four\n").replace("# exit 3", ""))
    found = problems(blocks(doc)[1], run_block(blocks(doc)[1], tmp_path, env))
    assert found[0].startswith('DOC.md:11: `echo "$X" \\` printed, not what the doc shows:\ntwo')
    assert found[1].startswith("DOC.md:11: `cat runs/a.txt; exit 3   ` exited 3, the doc says 0")


def test_files_written_outside_gitignored_folders_are_named(tmp_path: Path) -> None:
    doc = tmp_path / "DOC.md"
    doc.write_text("```bash runnable\necho x > stray.txt && mkdir -p runs && echo y > runs/ok\n```\n")
    found, _ = run_doc(doc, tmp_path / "work")
    assert found == ["DOC.md: written outside gitignored folders: stray.txt"]


@pytest.mark.parametrize("doc", runnable_docs(), ids=lambda d: d.name)
def test_the_docs_examples_run_as_written(doc: Path, tmp_path: Path) -> None:
    found, ran = run_doc(doc, tmp_path)
    assert ran, f"{doc.name}: no runnable block"
    assert not found, "\n\n".join(found)


def test_the_docs_that_promise_runnable_examples_have_them() -> None:
    docs = {d.relative_to(ROOT).as_posix() for d in runnable_docs()}
    assert docs >= {"docs/ANALYSIS.md", "docs/EXPORT.md", "docs/METRICS.md"}
