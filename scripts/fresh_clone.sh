#!/usr/bin/env bash
# The README's first line in a fresh clone of this checkout (its last commit), then
# `vge app --help` and `vge --help` in the same shell: the README leaves a working `vge`.
# Run by CI (.ci/run); needs git and the package index (pip install).
set -euo pipefail
cd "$(dirname "$0")/.."
WORK="$(mktemp -d)"
trap 'rm -rf "$WORK"' EXIT
git clone --quiet . "$WORK/clone"
cd "$WORK/clone"
# The first line of the README's first ```bash block, as a reader copies it.
FIRST="$(awk '/^```bash/ { getline; print; exit }' README.md)"
echo "fresh clone: $FIRST"
if ! bash -c "set -euo pipefail
$FIRST
vge app --help
vge --help" > "$WORK/log" 2>&1; then
  cat "$WORK/log"
  echo "fresh clone: the README's first line does not leave a working vge" >&2
  exit 1
fi
grep -q "Open the dashboard:  vge app logs-replayed" "$WORK/log" || {
  cat "$WORK/log"
  echo "fresh clone: vge demo's closing hint is not the command the shell runs" >&2
  exit 1
}
echo "fresh clone: ok (vge demo, vge app --help, vge --help)"
