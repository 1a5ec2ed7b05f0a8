#!/usr/bin/env bash
# Runs the whole test suite on a fresh machine: virtual environment, packages, Debian's chromium for the
# browser tests (installed with apt-get when missing), lint and type checks, then pytest. Extra arguments go to pytest.
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
echo "==> lint (ruff) and types (mypy)"
.venv/bin/ruff check studio tests bench scripts
.venv/bin/mypy
echo "==> tests"
# Two workers (the machine has two cores), each handed the next test when it is free (no test is in a group, so
# "loadgroup" hands them out one by one), the slowest browser walks first (tests/conftest.py, decision 099).
# No reruns: a test that fails under load is a bug in the test or the code. The 15 slowest tests are listed.
exec .venv/bin/python -m pytest -n 2 --dist loadgroup --durations=15 -ra "$@"
