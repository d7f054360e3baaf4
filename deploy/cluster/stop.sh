#!/usr/bin/env bash
# Stops a cluster started by start.sh DIR (SIGTERM: servers finish cleanly).
set -euo pipefail
dir=${1:?usage: stop.sh DIR}
[[ -f "$dir/pids" ]] || { echo "stop.sh: no $dir/pids" >&2; exit 1; }
tac "$dir/pids" | while read -r pid; do kill "$pid" 2>/dev/null || true; done
rm -f "$dir/pids"
