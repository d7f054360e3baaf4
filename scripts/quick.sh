#!/usr/bin/env bash
# The quick tier, for the edit–test loop (a few minutes warm on 2 cores), with no
# transport linked: formatting, clippy over the core (library, its unit tests, the
# integration binary) without the service and CLI features, the API docs, the
# library's unit and property tests and the integration binary at quick sizes — no
# zenoh, tokio or plotters — and the Python client's tests that need no server. Not run here: the
# service, the CLI, the Python tests against the server, the full-size differential
# runs (scripts/test.sh, what CI runs).
set -euo pipefail
cd "$(dirname "$0")/.."
export OPENBLAS_NUM_THREADS=${OPENBLAS_NUM_THREADS:-1}   # small SDPs are faster single-threaded
export RISKPLAN_TEST_TIER=quick
export PROPTEST_CASES=${PROPTEST_CASES:-64}
# the layer crates below the service, and the root package without the service and CLI
LAYERS=(-p riskplan-math -p riskplan-scene -p riskplan-certify -p riskplan-plan -p riskplan-app)
ROOT=(-p riskplan --no-default-features)
echo "== cargo fmt --check"
cargo fmt --all -- --check
echo "== cargo clippy (the layers below the service: libraries, unit tests; the integration binary; no transport)"
cargo clippy "${LAYERS[@]}" --lib --tests -- -D warnings
cargo clippy "${ROOT[@]}" --lib --tests -- -D warnings
echo "== the API docs (rustdoc: no broken, ambiguous or private intra-doc links; no transport)"
RUSTDOCFLAGS="-D warnings" cargo doc "${LAYERS[@]}" --no-deps
echo "== the layers' unit/property tests and doc tests, the integration binary (quick sizes, no transport)"
cargo test "${LAYERS[@]}"
cargo test "${ROOT[@]}" --test integration
echo "== Python client tests that need no server"
VENV=${RISKPLAN_VENV:-${TMPDIR:-/tmp}/riskplan-venv}
if ! "$VENV/bin/python" -c 'import riskplan, jsonschema' 2>/dev/null; then
    python3 -m venv "$VENV"
    "$VENV/bin/pip" install -q -e './clients/python[plot,test]'
fi
"$VENV/bin/python" -m pytest clients/python/tests/test_offline.py -q
