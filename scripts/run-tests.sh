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
# Two workers (the machine has two cores): the browser tests one after another on one, the rest on the other.
# A test that fails runs once more (a test failing twice fails the run); "RERUN" in the summary names every test
# that needed it: CI machines are slower and busier than ours (CI failed on timing there that never showed here).
exec .venv/bin/python -m pytest -n 2 --dist loadgroup --reruns 1 --reruns-delay 2 -raR "$@"
