#!/usr/bin/env bash
# Creates .venv (Python 3.11+) and installs the studio, only when what it installs changed: the pinned packages of
# scripts/runtime-requirements.txt without pip's resolver (docs/decisions/091), and the given extras, if any (the
# test command's, "test,mesh", pinned in scripts/test-requirements.txt, also without the resolver, installed at the
# same time; any others after).
# Usage: bash scripts/bootstrap.sh [extras]   e.g. "test,mesh"
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
EXTRAS="${1:-}"
PY="${PYTHON:-python3}"
VPY="$ROOT/.venv/bin/python"
LOCK="$ROOT/scripts/runtime-requirements.txt"
#: Seconds the first install usually takes here (bench/bench_install.py, bench/README.md).
ABOUT=30
if [ ! -x "$VPY" ]; then
  echo "==> creating the virtual environment in .venv"
  "$PY" -m venv "$ROOT/.venv"
fi
STAMP="$ROOT/.venv/.installed-$(cat "$ROOT/pyproject.toml" "$LOCK" "$ROOT/scripts/test-requirements.txt" | sha1sum | cut -c1-12)-${EXTRAS//,/_}"
if [ ! -f "$STAMP" ]; then
  export PIP_DISABLE_PIP_VERSION_CHECK=1
  count="$(grep -c '^[a-zA-Z]' "$LOCK")"
  echo "==> installing the studio and the $count packages it needs (first time only: about $ABOUT s)"
  EXTRAS_PID=""
  if [ "$EXTRAS" = "test,mesh" ]; then
    # The test command's extras, pinned beside the run-time ones (scripts/test-requirements.txt): no resolver. They
    # install while the run-time packages do: no package is in both lists and no file in two packages
    # (tests/test_install.py), and two pips at once take about half the time of one after the other (bench/README.md).
    echo "==> and beside them, the extras: $EXTRAS"
    EXTRAS_LOG="$(mktemp)"
    "$VPY" -m pip install --no-deps --no-compile --quiet -r "$ROOT/scripts/test-requirements.txt" >"$EXTRAS_LOG" 2>&1 &
    EXTRAS_PID=$!
  fi
  set +e
  "$VPY" -m pip install --no-deps --no-compile --progress-bar off -r "$LOCK" -e "$ROOT" 2>&1 \
    | "$VPY" "$ROOT/scripts/install_progress.py" --packages "$((count + 1))" --about "$ABOUT"
  status=("${PIPESTATUS[@]}")
  set -e
  if [ "${status[0]}" -ne 0 ]; then
    echo "Installing the studio's packages failed (see what pip said above). Check the internet connection and" \
      "run the command again." >&2
    [ -n "$EXTRAS_PID" ] && kill "$EXTRAS_PID" 2>/dev/null
    exit 1
  fi
  if [ -n "$EXTRAS_PID" ]; then
    set +e
    wait "$EXTRAS_PID"
    extras_status=$?
    set -e
    grep -v "^WARNING: Location" "$EXTRAS_LOG" || true
    rm -f "$EXTRAS_LOG"
    if [ "$extras_status" -ne 0 ]; then
      echo "Installing the test packages failed (see what pip said above)." >&2
      exit 1
    fi
  elif [ -n "$EXTRAS" ]; then
    echo "==> installing the extras: $EXTRAS"
    "$VPY" -m pip install --quiet -e "$ROOT[$EXTRAS]" 2>&1 | grep -v "^WARNING: Location" || true
  fi
  # Loading the studio once also keeps its modules compiled, even where the environment says not to
  # (PYTHONDONTWRITEBYTECODE): every later start then reads them instead of compiling again (bench/bench_bytecode.py).
  PYTHONDONTWRITEBYTECODE="" "$VPY" -c "import studio.app" \
    || { echo "The studio's packages are installed but do not load (see above)." >&2; exit 1; }
  touch "$STAMP"
fi
