"""The repository explains itself: nothing in it cites the old contract by name or points to
the shared directory beside the repository. `FORBIDDEN` is the pattern of the grep a reviewer
runs over code, docs, tests, app, schemas, benchmarks, scripts and the bundled sample; it
must find nothing. Code and docs cite docs/PROTOCOL.md instead ("PROTOCOL §n")."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# Spelled in pieces so that this file does not match itself.
FORBIDDEN = re.compile("SP" + "EC" + r"|\.\./" + "shared")
_SKIP_DIRS = {".git", ".venv", ".ci-venv", "__pycache__", "build", "dist", "node_modules"}


def repository_files() -> list[Path]:
    """The files of the repository: git's tracked and new, not ignored files; without git,
    every file outside virtual environments, caches and build output."""
    try:
        listed = subprocess.run(
            ["git", "ls-files", "--cached", "--others", "--exclude-standard", "-z"],
            cwd=ROOT,
            capture_output=True,
            check=True,
        ).stdout.decode()
        paths = [ROOT / name for name in listed.split("\0") if name]
    except (OSError, subprocess.CalledProcessError):
        paths = [
            p
            for p in ROOT.rglob("*")
            if not _SKIP_DIRS & set(p.relative_to(ROOT).parts)
            and not any(part.endswith((".egg-info", "_cache")) for part in p.parts)
        ]
    return sorted(p for p in paths if p.is_file())


def test_nothing_points_outside_the_repository() -> None:
    files = repository_files()
    assert len(files) > 200 and ROOT / "docs" / "PROTOCOL.md" in files
    found = []
    for path in files:
        data = path.read_bytes()
        if b"\0" in data:  # binary (images, Parquet): not text anyone reads
            continue
        for number, line in enumerate(data.decode("utf-8", "replace").splitlines(), 1):
            if FORBIDDEN.search(line):
                found.append(f"{path.relative_to(ROOT)}:{number}: {line.strip()[:120]}")
    assert not found, "\n".join(found)
