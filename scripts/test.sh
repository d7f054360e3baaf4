#!/usr/bin/env bash
# The whole test suite: formatting, lints, the math core alone (no zenoh/tokio),
# every Rust test of every feature, then the Python client's tests against the real
# server binary. Run from anywhere; needs scripts/setup-debian.sh once.
set -euo pipefail
cd "$(dirname "$0")/.."
export OPENBLAS_NUM_THREADS=${OPENBLAS_NUM_THREADS:-1}   # small SDPs are faster single-threaded
TARGET=${CARGO_TARGET_DIR:-target}
echo "== cargo fmt --check"
cargo fmt --all -- --check
echo "== cargo clippy (core, no default features)"
cargo clippy --no-default-features --all-targets -- -D warnings
echo "== cargo clippy (all features)"
cargo clippy --all-targets -- -D warnings
echo "== core tests without the service layer"
cargo test --no-default-features --lib
echo "== all Rust tests"
cargo test
echo "== Python client tests (against the real server)"
cargo build --release --bin riskplan
VENV=${RISKPLAN_VENV:-${TMPDIR:-/tmp}/riskplan-venv}
[ -x "$VENV/bin/python" ] || python3 -m venv "$VENV"
"$VENV/bin/pip" install -q -e './clients/python[plot,test]'
RISKPLAN_BIN="$TARGET/release/riskplan" "$VENV/bin/python" -m pytest clients/python/tests -q
