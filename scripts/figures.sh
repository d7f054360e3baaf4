#!/usr/bin/env bash
# Regenerates the figures of docs/figures/ from the reference scenes in scenes/.
# Usage: scripts/figures.sh [path/to/riskplan]   (default: cargo run --release)
set -euo pipefail
cd "$(dirname "$0")/.."
S=scenes
if [ $# -ge 1 ]; then RP=("$1"); else cargo build --release --quiet; RP=(target/release/riskplan); fi
mkdir -p docs/figures
"${RP[@]}" contour --scene "$S/illustrative-1.json" --delta 0.2 0.1 0.07 0.05 --mc 20000 \
  --window -0.7 0.7 -0.7 0.7 --out docs/figures/illustrative-1-contours.svg
"${RP[@]}" contour --scene "$S/example-a1-2d.json" --mc 5000 --out docs/figures/example-a1-2d-contours.svg
"${RP[@]}" contour --scene "$S/illustrative-2.json" --time 0 0.5 1 --mc 5000 --out docs/figures/illustrative-2-contours.svg
"${RP[@]}" contour --scene "$S/example-a2-3d.json" --slice x3=0 --mc 5000 --out docs/figures/example-a2-3d-slice-x3-0.svg
# the Δ-contours of every bound: illustrative-1 at three Δ, a disk with a Gaussian centre,
# a pedestrian with velocity error at three instants
mkdir -p docs/figures/bounds
for d in 0.1 0.01 0.001; do
  "${RP[@]}" contour --scene "$S/illustrative-1.json" --delta "$d" --bound each --mc 20000 --grid 200 --mc-grid 80 \
    --window -1 1 -1 1 --out "docs/figures/bounds/illustrative-1-delta-$d.svg"
done
"${RP[@]}" contour --scene tests/scenes/bounds/gaussian-centre-disk.json --delta 0.001 --bound each --mc 20000 \
  --grid 200 --mc-grid 80 --window -3.6 3.6 -3.6 3.6 --out docs/figures/bounds/gaussian-centre-disk-delta-0.001.svg
"${RP[@]}" contour --scene tests/scenes/bounds/pedestrian.json --delta 0.01 --time 0 4 8 --bound auto --mc 5000 \
  --grid 200 --mc-grid 70 --out docs/figures/bounds/pedestrian-delta-0.01.svg
# plans: the default rrt-sos on every planning scene (seed 1); the paper's RRT-SOS with improve
"${RP[@]}" plan --scene "$S/illustrative-3.json" --planner rrt-sos-paper --improve --out /dev/null \
  --figure docs/figures/plan-illustrative-3-paper-improve.svg
for s in illustrative-3 illustrative-4 example-b-lane-change example-c-delivery example-d1-cluttered-2d example-d2-cluttered-3d; do
  "${RP[@]}" plan --scene "$S/$s.json" --out /dev/null --figure "docs/figures/plan-$s.svg"
done
"${RP[@]}" plan --scene "$S/illustrative-3.json" --planner mc-rrt --out /dev/null --figure docs/figures/plan-illustrative-3-mc-rrt.svg
