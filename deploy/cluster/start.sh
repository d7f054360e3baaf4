#!/usr/bin/env bash
# Starts a riskplan cluster on this machine (deploy/cluster/README.md): one router,
# one primary and REPLICAS replicas, each server with its own data directory under
# DIR, logs in DIR/*.log, process ids in DIR/pids. Stop it with stop.sh DIR.
# Usage: deploy/cluster/start.sh [--metrics HOST:PORT] DIR [REPLICAS=1] [ROUTER_ENDPOINT=tcp/127.0.0.1:7446]
# --metrics HOST:PORT: each server serves Prometheus metrics (serve --metrics), the
# primary on HOST:PORT, replica k on HOST:PORT+k (deploy/prometheus/prometheus.yml
# scrapes 127.0.0.1:9464 and up). Off by default.
# RISKPLAN (default: riskplan on PATH, else target/release/riskplan) is the binary.
set -euo pipefail
usage="usage: start.sh [--metrics HOST:PORT] DIR [REPLICAS] [ROUTER_ENDPOINT]"
metrics=""
args=()
while [[ $# -gt 0 ]]; do
  case "$1" in
    --metrics) metrics=${2:?$usage}; shift 2 ;;
    --metrics=*) metrics=${1#--metrics=}; shift ;;
    *) args+=("$1"); shift ;;
  esac
done
set -- "${args[@]+"${args[@]}"}"
dir=${1:?$usage}
replicas=${2:-1}
router=${3:-tcp/127.0.0.1:7446}
metrics_host="" metrics_port=""
if [[ -n "$metrics" ]]; then
  metrics_host=${metrics%:*}
  metrics_port=${metrics##*:}
  [[ "$metrics_port" =~ ^[0-9]+$ && -n "$metrics_host" && "$metrics_host" != "$metrics" ]] \
    || { echo "start.sh: --metrics wants HOST:PORT (e.g. 127.0.0.1:9464), got '$metrics'" >&2; exit 2; }
fi
# the --metrics flag of the server with index k (0: the primary, k: replica k), if asked for
metrics_of() {
  [[ -n "$metrics" ]] && echo "--metrics" "$metrics_host:$((metrics_port + $1))"
  return 0
}
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
# shellcheck disable=SC2046  # metrics_of prints two words or none
"$bin" serve --mode client --connect "$router" --server-id primary --data "$dir/primary" $(metrics_of 0) 2> "$dir/primary.log" &
echo $! >> "$dir/pids"
wait_line "$dir/primary.log" "riskplan: ready" 120
for k in $(seq 1 "$replicas"); do
  # shellcheck disable=SC2046
  "$bin" serve --mode client --connect "$router" --replica --server-id "replica-$k" --data "$dir/replica-$k" $(metrics_of "$k") 2> "$dir/replica-$k.log" &
  echo $! >> "$dir/pids"
  wait_line "$dir/replica-$k.log" "riskplan: ready" 120
done
echo "start.sh: router on $router, a primary and $replicas replica(s); clients connect to $router"
if [[ -n "$metrics" ]]; then
  echo "start.sh: metrics on http://$metrics_host:$metrics_port/metrics (primary) to http://$metrics_host:$((metrics_port + replicas))/metrics (replica-$replicas)"
fi
