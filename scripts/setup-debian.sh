#!/usr/bin/env bash
# Installs what riskplan needs on a fresh Debian 12 machine (run as root or with sudo).
# Idempotent: packages already present are not reinstalled.
#   libopenblas-dev, libgfortran-12-dev  LAPACK for Clarabel's SDP cones (feature sdp-openblas)
#   fonts-dejavu-core                    a TrueType font for figure labels
#   python3-venv                         the Python client's tests run in a virtualenv
#   librsvg2-bin                         rsvg-convert renders the SVG figures in the figure tests
# Rust itself (cargo, rustc >= 1.85 with clippy and rustfmt) comes from rustup.
set -euo pipefail
pkgs=(libopenblas-dev libgfortran-12-dev fonts-dejavu-core python3-venv pkg-config librsvg2-bin)
missing=()
for p in "${pkgs[@]}"; do
  dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  SUDO=""
  [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${missing[@]}"
fi
if ! command -v cargo >/dev/null 2>&1; then
  echo "cargo not found: install Rust with rustup (https://rustup.rs), then re-run" >&2
  exit 1
fi
for c in clippy rustfmt; do
  if ! cargo "${c/rustfmt/fmt}" --version >/dev/null 2>&1; then
    rustup component add "$c"
  fi
done
