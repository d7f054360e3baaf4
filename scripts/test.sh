#!/usr/bin/env bash
# The full tier (what CI runs): formatting, clippy once over the workspace (the layer
# crates, the root package, crates/riskplan-oracle, crates/riskplan-testkit), its API
# docs without warnings, a build of the layers below the service alone (no zenoh, tokio,
# clap or plotters), every Rust test of the workspace once at full sizes, then the Python client's tests against the real
# server binary built by that same test run. Run from anywhere; needs scripts/setup-debian.sh once.
set -euo pipefail
cd "$(dirname "$0")/.."
export OPENBLAS_NUM_THREADS=${OPENBLAS_NUM_THREADS:-1}   # small SDPs are faster single-threaded
export RISKPLAN_TEST_TIER=full
TARGET=${CARGO_TARGET_DIR:-target}
echo "== cargo fmt --check"
cargo fmt --all -- --check
echo "== cargo clippy (the workspace, all targets, all features)"
cargo clippy --workspace --all-targets --all-features -- -D warnings
echo "== the API docs (rustdoc: no broken, ambiguous or private intra-doc links)"
RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps --all-features
echo "== the shipped build (default features)"
cargo check --lib --bins
echo "== the layers below the service build alone (no service, no CLI)"
cargo check --no-default-features --lib
echo "== the service's messages and handlers without the transport (what fuzz/ builds)"
cargo check -p riskplan-service --lib
echo "== every Rust test of the workspace: unit, property, integration (full sizes), doc tests"
cargo test --workspace --all-features
echo "== Python client tests (against the server binary of the test build)"
VENV=${RISKPLAN_VENV:-${TMPDIR:-/tmp}/riskplan-venv}
[ -x "$VENV/bin/python" ] || python3 -m venv "$VENV"
"$VENV/bin/pip" install -q -e './clients/python[plot,test]'
RISKPLAN_BIN="$TARGET/debug/riskplan" RISKPLAN_REQUIRE_SERVER=1 "$VENV/bin/python" -m pytest clients/python/tests -q
