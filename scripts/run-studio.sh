#!/usr/bin/env bash
# Starts Teaching Studio on http://127.0.0.1:8080 with the bundled "stack-cup" example session; open the address it
# prints (http://127.0.0.1:8080/?key=..., a new key at each start: only that page may drive the studio).
# Extra arguments go to `studio` (e.g. --port 9000, --session pick-place); with --robot it also installs what
# driving a real Baxter needs (the "robot" extra).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
EXTRAS=""
for arg in "$@"; do
  case "$arg" in --robot | --robot=*) EXTRAS="robot" ;; esac
done
bash "$ROOT/scripts/bootstrap.sh" "$EXTRAS"
echo "==> starting the studio"
exec "$ROOT/.venv/bin/studio" "$@"
