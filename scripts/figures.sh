#!/usr/bin/env bash
# Regenerates the contour figures of docs/figures/ from the reference scenes.
# Usage: scripts/figures.sh [path/to/riskplan]   (default: cargo run --release)
set -euo pipefail
cd "$(dirname "$0")/.."
S=${RISKPLAN_REFERENCE_SCENES:-../shared/reference/scenes}
if [ $# -ge 1 ]; then RP=("$1"); else cargo build --release --quiet; RP=(target/release/riskplan); fi
mkdir -p docs/figures
"${RP[@]}" contour --scene "$S/illustrative-1.json" --delta 0.2 0.1 0.07 0.05 --mc 20000 \
  --window -0.7 0.7 -0.7 0.7 --out docs/figures/illustrative-1-contours.svg
"${RP[@]}" contour --scene "$S/example-a1-2d.json" --mc 5000 --out docs/figures/example-a1-2d-contours.svg
"${RP[@]}" contour --scene "$S/illustrative-2.json" --time 0 0.5 1 --mc 5000 --out docs/figures/illustrative-2-contours.svg
"${RP[@]}" contour --scene "$S/example-a2-3d.json" --slice x3=0 --mc 5000 --out docs/figures/example-a2-3d-slice-x3-0.svg
