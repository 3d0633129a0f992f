"""`python -m replay.schemas [DIR]`: regenerate the JSON Schemas (default: ./schemas)."""

from __future__ import annotations

import sys

from .io import write_schemas

if __name__ == "__main__":
    target = sys.argv[1] if len(sys.argv) > 1 else "schemas"
    for path in write_schemas(target):
        print(path)
