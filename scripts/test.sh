#!/usr/bin/env bash
# The whole test suite: formatting, lints, the math core alone (no zenoh/tokio),
# then every test of every feature. Run from anywhere; needs scripts/setup-debian.sh once.
set -euo pipefail
cd "$(dirname "$0")/.."
export OPENBLAS_NUM_THREADS=${OPENBLAS_NUM_THREADS:-1}   # small SDPs are faster single-threaded
echo "== cargo fmt --check"
cargo fmt --all -- --check
echo "== cargo clippy (core, no default features)"
cargo clippy --no-default-features --all-targets -- -D warnings
echo "== cargo clippy (all features)"
cargo clippy --all-targets -- -D warnings
echo "== core tests without the service layer"
cargo test --no-default-features --lib
echo "== all tests"
cargo test
