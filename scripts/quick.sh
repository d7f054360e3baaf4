#!/usr/bin/env bash
# The quick tier, for the edit–test loop (a few minutes warm on 2 cores): formatting,
# clippy once over every target and feature, the library's unit and property tests and
# the integration-test binary at quick sizes. Not run here: the Python client against
# the server and the full-size differential runs (scripts/test.sh, what CI runs).
set -euo pipefail
cd "$(dirname "$0")/.."
export OPENBLAS_NUM_THREADS=${OPENBLAS_NUM_THREADS:-1}   # small SDPs are faster single-threaded
export RISKPLAN_TEST_TIER=quick
export PROPTEST_CASES=${PROPTEST_CASES:-64}
echo "== cargo fmt --check"
cargo fmt --all -- --check
echo "== cargo clippy (all targets, all features)"
cargo clippy --all-targets --all-features -- -D warnings
echo "== library unit/property tests and the integration binary (quick sizes)"
cargo test --all-features --lib --test integration
