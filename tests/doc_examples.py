"""The docs' runnable examples: found, run as a reader runs them from a fresh clone, checked.

A fenced block is an example to run when its info string says so:

- ```` ```bash runnable ````: a script; it runs in `bash -euo pipefail` and must exit 0.
- ```` ```console runnable ````: a session; each line `$ COMMAND` (continued on the next
  line after a trailing `\\`) is run, and the lines up to the next `$ ` are its output,
  which must be what the command prints (stdout and stderr together, trailing spaces
  ignored; a command shown without output is not compared). It must exit 0, or N when its
  line ends with `# exit N`. Variables set by one command are seen by the next (one shell).

The blocks of one doc run in order, in a copy of the repository (its tracked and untracked,
not ignored, files) with `vge` on PATH, as a reader in a fresh clone with the README's
first line done; afterwards, every file they wrote must be ignored by `.gitignore` (the
examples write under gitignored folders, or /tmp). Rich prints its tables at most 200
columns wide (`COLUMNS`), without colour.

`python -m tests.doc_examples docs/X.md ...` runs the docs' examples and prints what
differs; `--update` writes what the commands print into the docs' console blocks.
"""

from __future__ import annotations

import argparse
import os
import re
import secrets
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

from .test_self_contained import ROOT, repository_files

OPENING = re.compile(r"^```(bash|console) runnable\s*$")
EXIT = re.compile(r"#\s*exit\s+(\d+)\s*$")
COLUMNS = 200
BLOCK_TIMEOUT = 900.0
"""Seconds one block may run (the slowest, a continuation of 312 episodes twice, takes
about a minute on a busy machine)."""


@dataclass
class Command:
    text: str
    """The command as a shell reads it (continuation lines joined with newlines)."""
    expected: list[str] | None
    """The output the doc shows (None: none shown, not compared)."""
    exit_code: int = 0
    output_lines: tuple[int, int] = (0, 0)
    """Where the shown output is in the doc: [first, last) line numbers (0-based)."""


@dataclass
class Block:
    doc: Path
    line: int
    """1-based line of the opening fence."""
    kind: str
    """`bash` or `console`."""
    body: list[str]
    commands: list[Command] = field(default_factory=list)

    @property
    def where(self) -> str:
        return f"{self.doc.name}:{self.line}"


def _commands(body: list[str], first: int) -> list[Command]:
    """The `$ ` commands of a console block and the output shown after each."""
    commands: list[Command] = []
    i = 0
    while i < len(body):
        if not body[i].startswith("$ "):
            raise ValueError(f"line {first + i + 1}: output before the first `$ ` command")
        lines = [body[i][2:]]
        while lines[-1].endswith("\\") and i + 1 < len(body):
            i += 1
            lines.append(body[i])
        i += 1
        start = i
        while i < len(body) and not body[i].startswith("$ "):
            i += 1
        match = EXIT.search(lines[-1])
        commands.append(
            Command(
                text="\n".join(lines),
                expected=body[start:i] or None,
                exit_code=int(match.group(1)) if match else 0,
                output_lines=(first + start, first + i),
            )
        )
    return commands


def blocks(doc: Path) -> list[Block]:
    """The runnable blocks of a markdown file, in order."""
    lines = doc.read_text(encoding="utf-8").splitlines()
    found = []
    i = 0
    while i < len(lines):
        opening = OPENING.match(lines[i])
        i += 1
        if not opening:
            continue
        start = i
        while i < len(lines) and not lines[i].startswith("```"):
            i += 1
        block = Block(doc, start, opening.group(1), lines[start:i])
        if block.kind == "console":
            block.commands = _commands(block.body, start)
        found.append(block)
        i += 1
    return found


def runnable_docs() -> list[Path]:
    """The repository's markdown files that hold a runnable block."""
    docs = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    return [d for d in docs if blocks(d)]


# ---------------------------------------------------------------------------- running


def workspace(dest: Path) -> Path:
    """A copy of the repository in `dest`, as a fresh clone (a git repository whose files
    are all untracked: `unignored_files` then tells what an example wrote)."""
    for path in repository_files():
        target = dest / path.relative_to(ROOT)
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(path, target)
    subprocess.run(["git", "init", "-q", str(dest)], check=True)
    return dest


def unignored_files(root: Path) -> set[str]:
    """Files of `root` that git does not ignore."""
    out = subprocess.run(
        ["git", "ls-files", "-z", "--others", "--exclude-standard"],
        cwd=root,
        capture_output=True,
        check=True,
    ).stdout
    return {p for p in out.decode().split("\0") if p}


def environment(cache: Path) -> dict[str, str]:
    """What the examples run with: the `vge` of this Python first on PATH (as after the
    README's `. .venv/bin/activate`), tables 200 columns wide without colour, a cache of
    their own."""
    bin_dir = str(Path(sys.executable).parent)
    env = {k: v for k, v in os.environ.items() if not k.startswith(("VGE_", "PYTEST"))}
    env.update(
        PATH=f"{bin_dir}{os.pathsep}{env.get('PATH', '')}",
        VIRTUAL_ENV=str(Path(bin_dir).parent),
        COLUMNS=str(COLUMNS),
        NO_COLOR="1",
        TERM="dumb",
        VGE_CACHE_DIR=str(cache),
    )
    return env


@dataclass
class Result:
    command: Command | None
    """The console command (None: a bash block as a whole)."""
    exit_code: int
    output: list[str]


def _lines(text: str) -> list[str]:
    lines = [line.rstrip() for line in text.splitlines()]
    while lines and not lines[-1]:
        lines.pop()
    return lines


def run_block(block: Block, cwd: Path, env: dict[str, str]) -> list[Result]:
    """Run one block in `cwd`; one result per console command (or one for a bash block)."""
    if block.kind == "bash":
        proc = subprocess.run(
            ["bash", "-euo", "pipefail", "-c", "\n".join(block.body)],
            cwd=cwd,
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            timeout=BLOCK_TIMEOUT,
        )
        return [Result(None, proc.returncode, _lines(proc.stdout.decode(errors="replace")))]
    mark = f"@@doc-example-{secrets.token_hex(8)}"
    script = ["exec 2>&1"]
    for k, command in enumerate(block.commands):
        script += [f"echo '{mark} start {k}'", command.text, f"echo \"{mark} exit {k} $?\""]
    proc = subprocess.run(
        ["bash", "-c", "\n".join(script)],
        cwd=cwd,
        env=env,
        stdout=subprocess.PIPE,
        timeout=BLOCK_TIMEOUT,
    )
    results: list[Result] = []
    current: list[str] = []
    for line in proc.stdout.decode(errors="replace").splitlines():
        if line.startswith(f"{mark} start "):
            current = []
        elif line.startswith(f"{mark} exit "):
            k, code = map(int, line.split()[2:4])
            results.append(Result(block.commands[k], code, _lines("\n".join(current))))
        else:
            current.append(line)
    if len(results) < len(block.commands):  # the shell itself ended early
        results.append(Result(block.commands[len(results)], proc.returncode, _lines("\n".join(current))))
    return results


def problems(block: Block, results: list[Result]) -> list[str]:
    """What differs from the doc: exit codes, and the output shown."""
    found = []
    for result in results:
        command = result.command
        if command is None:
            if result.exit_code != 0:
                tail = "\n".join(result.output[-20:])
                found.append(f"{block.where}: exit {result.exit_code}\n{tail}")
            continue
        head = command.text.splitlines()[0]
        if result.exit_code != command.exit_code:
            tail = "\n".join(result.output[-20:])
            found.append(
                f"{block.where}: `{head}` exited {result.exit_code}, the doc says "
                f"{command.exit_code}\n{tail}"
            )
        if command.expected is not None and _lines("\n".join(command.expected)) != result.output:
            shown = "\n".join(result.output)
            found.append(f"{block.where}: `{head}` printed, not what the doc shows:\n{shown}")
    if len(results) < len(block.commands or [None]):
        found.append(f"{block.where}: the block stopped after {len(results)} command(s)")
    return found


def run_doc(doc: Path, root: Path) -> tuple[list[str], list[tuple[Block, list[Result]]]]:
    """Every runnable block of `doc`, in order, in a fresh workspace under `root`: the
    problems found (with the files written outside gitignored folders) and the results."""
    work = workspace(root / "repo")
    env = environment(root / "cache")
    before = unignored_files(work)
    found: list[str] = []
    ran = []
    for block in blocks(doc):
        results = run_block(block, work, env)
        found += problems(block, results)
        ran.append((block, results))
    written = sorted(unignored_files(work) - before)
    if written:
        found.append(f"{doc.name}: written outside gitignored folders: {', '.join(written[:10])}")
    return found, ran


def update(doc: Path, ran: list[tuple[Block, list[Result]]]) -> None:
    """Write what each console command printed into `doc`, after the command."""
    lines = doc.read_text(encoding="utf-8").splitlines()
    edits = [
        (r.command.output_lines, r.output) for _, results in ran for r in results if r.command
    ]
    for (start, end), output in sorted(edits, reverse=True):
        lines[start:end] = output
    doc.write_text("\n".join(lines) + "\n", encoding="utf-8")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("docs", nargs="*", type=Path)
    parser.add_argument("--update", action="store_true", help="write the outputs into the docs")
    args = parser.parse_args(argv)
    failed = 0
    for doc in args.docs or runnable_docs():
        with tempfile.TemporaryDirectory(prefix="vge-doc-") as tmp:
            found, ran = run_doc(doc.resolve(), Path(tmp))
        for problem in found:
            print(problem, end="\n\n")
        failed += bool(found)
        if args.update:
            update(doc, ran)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
