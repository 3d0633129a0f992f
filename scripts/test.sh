#!/usr/bin/env bash
# Set up a fresh virtual environment from the repo's own files and run the test suite.
# Used verbatim by the README and by CI (.ci/run).
set -euo pipefail
cd "$(dirname "$0")/.."
VENV="${VGE_VENV:-.venv}"
PY="${PYTHON:-python3}"
if [ ! -x "$VENV/bin/python" ]; then
  "$PY" -m venv "$VENV"
fi
"$VENV/bin/python" -m pip install --quiet --upgrade pip
"$VENV/bin/python" -m pip install --quiet -e '.[test,ray,export]'
# The dashboard's browser tests (Playwright) drive Debian's Chromium: no browser download.
if [ ! -x /usr/bin/chromium ]; then
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
  $SUDO env DEBIAN_FRONTEND=noninteractive apt-get update -qq
  $SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null
fi
"$VENV/bin/ruff" check replay vge_analytics app tests benchmarks
# loadgroup: the browser tests share one dashboard server and one Chromium (tests/app/conftest.py).
"$VENV/bin/python" -m pytest -n 2 --dist loadgroup -p no:cacheprovider "$@"
