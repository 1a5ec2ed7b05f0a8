#!/usr/bin/env bash
# Runs the whole test suite on a fresh machine: virtual environment, packages, Debian's chromium for the
# browser tests (installed with apt-get when missing), lint, then pytest with the type check running beside it (its
# result is printed after the tests'; either failing fails the command). Extra arguments go to pytest.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
bash scripts/bootstrap.sh "test,mesh"
if [ ! -x /usr/bin/chromium ]; then
  echo "==> installing Debian's chromium for the browser tests"
  SUDO=""
  [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq chromium >/dev/null
fi
echo "==> lint (ruff); types (mypy) run beside the tests and are reported after them"
.venv/bin/ruff check studio tests bench scripts
TYPES_LOG="$(mktemp)"
.venv/bin/mypy >"$TYPES_LOG" 2>&1 &
TYPES_PID=$!
trap 'kill "$TYPES_PID" 2>/dev/null || true; rm -f "$TYPES_LOG"' EXIT
echo "==> tests"
# Python keeps what it compiles, even where the environment says not to: the studios, workers and commands the
# tests start then read the modules the first of them compiled (bench/bench_bytecode.py).
export PYTHONDONTWRITEBYTECODE=""
# Three workers on the two cores: the tests wait on the clock part of the time (a robot moving in real time, a
# studio starting), and a third worker uses the cores meanwhile (bench/README.md). Each is handed the next test when
# it is free, the slowest browser walks first (tests/conftest.py, decision 099); the fixtures that train are built
# once for all three (run_once, decision 100).
# No reruns: a test that fails under load is a bug in the test or the code. The 15 slowest tests are listed.
set +e
.venv/bin/python -m pytest -n 3 --dist loadgroup --durations=15 -ra "$@"
tests=$?
wait "$TYPES_PID"
types=$?
set -e
echo "==> types (mypy)"
cat "$TYPES_LOG"
if [ "$tests" -ne 0 ]; then exit "$tests"; fi
exit "$types"
