#!/usr/bin/env bash
# Starts a riskplan cluster on this machine (deploy/cluster/README.md): one router,
# one primary and REPLICAS replicas, each server with its own data directory under
# DIR, logs in DIR/*.log, process ids in DIR/pids. Stop it with stop.sh DIR.
# Usage: deploy/cluster/start.sh DIR [REPLICAS=1] [ROUTER_ENDPOINT=tcp/127.0.0.1:7446]
# RISKPLAN (default: riskplan on PATH, else target/release/riskplan) is the binary.
set -euo pipefail
dir=${1:?usage: start.sh DIR [REPLICAS] [ROUTER_ENDPOINT]}
replicas=${2:-1}
router=${3:-tcp/127.0.0.1:7446}
here=$(cd "$(dirname "$0")" && pwd)
bin=${RISKPLAN:-$(command -v riskplan || echo "$here/../../target/release/riskplan")}
mkdir -p "$dir"
: > "$dir/pids"
wait_line() {  # file, text, seconds
  for _ in $(seq 1 $((${3} * 10))); do
    grep -q "$2" "$1" 2>/dev/null && return 0
    sleep 0.1
  done
  echo "start.sh: no '$2' in $1 after $3 s:" >&2
  tail -5 "$1" >&2
  return 1
}
"$bin" router --listen "$router" 2> "$dir/router.log" &
echo $! >> "$dir/pids"
wait_line "$dir/router.log" "router listening" 30
"$bin" serve --mode client --connect "$router" --server-id primary --data "$dir/primary" 2> "$dir/primary.log" &
echo $! >> "$dir/pids"
wait_line "$dir/primary.log" "riskplan: ready" 120
for k in $(seq 1 "$replicas"); do
  "$bin" serve --mode client --connect "$router" --replica --server-id "replica-$k" --data "$dir/replica-$k" 2> "$dir/replica-$k.log" &
  echo $! >> "$dir/pids"
  wait_line "$dir/replica-$k.log" "riskplan: ready" 120
done
echo "start.sh: router on $router, a primary and $replicas replica(s); clients connect to $router"
