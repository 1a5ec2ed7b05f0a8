#!/usr/bin/env bash
# Creates .venv (Python 3.11+) and installs the studio with the given extras, only when pyproject.toml changed.
# Usage: source scripts/bootstrap.sh [extras]   e.g. "test,mesh"
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
EXTRAS="${1:-}"
PY="${PYTHON:-python3}"
if [ ! -x "$ROOT/.venv/bin/python" ]; then
  echo "==> creating the virtual environment in .venv"
  "$PY" -m venv "$ROOT/.venv"
fi
STAMP="$ROOT/.venv/.installed-$(sha1sum "$ROOT/pyproject.toml" | cut -c1-12)-${EXTRAS//,/_}"
if [ ! -f "$STAMP" ]; then
  echo "==> installing the studio and its dependencies (first time: about a minute)"
  "$ROOT/.venv/bin/python" -m pip install --quiet --disable-pip-version-check --upgrade pip 2>&1 | grep -v "^WARNING: Location" || true
  spec="$ROOT"
  [ -n "$EXTRAS" ] && spec="$ROOT[$EXTRAS]"
  "$ROOT/.venv/bin/python" -m pip install --quiet --disable-pip-version-check -e "$spec" 2>&1 | grep -v "^WARNING: Location" || true
  "$ROOT/.venv/bin/python" -c "import studio, viser, pinocchio, hmmlearn, sklearn" \
    || { echo "installing the dependencies failed" >&2; exit 1; }
  touch "$STAMP"
fi
