#!/usr/bin/env bash
# Reproduces every experiment of the paper riskplan implements (Jasour, Han, Williams, RSS 2021):
# Illustrative Examples 1–4 and Examples A–D, each with every planner the paper used on it (and
# ours beside them), and writes docs/reproduction.md.
#
# Usage: scripts/reproduce.sh [path/to/riskplan]
#   With no argument it builds the release binary (cargo build --release --quiet) and uses
#   ${CARGO_TARGET_DIR:-target}/release/riskplan. Run from anywhere; it works in the repository root.
#
# Environment knobs [defaults]:
#   SEEDS          seeds per planner and scene in the benchmark              [5]
#   TIME_LIMIT     time limit of every planner run, seconds                   [60]
#   AUDIT_SAMPLES  Monte Carlo scenarios per audited point of every plan     [20000]
#   AUDIT_TIMES    audited times per piece of every plan                     [50]
#   SPOT_MC        Monte Carlo samples per spot point of the contour scenes  [1000000]
#   TRAJ_MC        Monte Carlo samples per time along the authors' printed
#                  trajectories and the straight-line controls                [20000]
#   TRAJ_TIMES     times along each of those trajectories                    [41]
#   CONTOUR_MC     Monte Carlo samples per grid point of the contour figures [5000]
#
# Every risk, verify, plan and bench call runs with --bound cantelli: the paper's bound (eq. 10,
# 12), which the reproduction is about; riskplan's default (auto) proves more (docs/design.md §5.13).
#
# What it does (every number of the report comes from these files; nothing is typed in):
#   1. scripts/reproduce_report.py prepare: the authors' printed time-varying SOS trajectories
#      (expected.trajectories.time_varying_sos.global of the scenes) and straight start–goal
#      lines as trajectory files (format v1), and the lists of risk and verify queries;
#   2. riskplan contour: the contour figures of Illustrative Examples 1–2 and Examples A-1, A-2;
#   3. riskplan risk: E[P], the Cantelli bound and a Monte Carlo estimate at the scenes' spot
#      points and along the authors' trajectories and the straight lines;
#   4. riskplan verify --method both: the authors' trajectories at the scene's Δ and slightly
#      above it, and the straight lines;
#   5. riskplan bench --suite paper: every planning scene × planner × seed, audited by Monte Carlo;
#   6. riskplan plan (seed 1) for each scene × planner of the benchmark: the figures, the plan
#      files, and riskplan verify --method both on each plan;
#   7. scripts/reproduce_report.py report: docs/reproduction.md.
#
# Outputs: docs/reproduction/ (raw results: run.json, bench.jsonl, bench-table.md, plans/,
# verify.jsonl, risk.jsonl, trajectories/, *-tasks.tsv, log.txt), docs/figures/repro/ (figures),
# docs/reproduction.md.
# Both output directories are emptied first. Exit status non-zero on any failure.
set -euo pipefail
cd "$(dirname "$0")/.."

export OPENBLAS_NUM_THREADS=1
# the knobs given in the environment (recorded, with the seeds and time limit, in the report's command)
KNOBS_SET=()
for v in AUDIT_SAMPLES AUDIT_TIMES SPOT_MC TRAJ_MC TRAJ_TIMES CONTOUR_MC; do
  if [ -n "${!v+x}" ]; then KNOBS_SET+=("$v=${!v}"); fi
done
SEEDS=${SEEDS:-5}
TIME_LIMIT=${TIME_LIMIT:-60}
AUDIT_SAMPLES=${AUDIT_SAMPLES:-20000}
AUDIT_TIMES=${AUDIT_TIMES:-50}
SPOT_MC=${SPOT_MC:-1000000}
TRAJ_MC=${TRAJ_MC:-20000}
TRAJ_TIMES=${TRAJ_TIMES:-41}
CONTOUR_MC=${CONTOUR_MC:-5000}
S=scenes
OUT=docs/reproduction
FIG=docs/figures/repro
PY=(python3 scripts/reproduce_report.py)

if [ $# -ge 1 ]; then
  RP=$1
else
  cargo build --release --quiet
  RP=${CARGO_TARGET_DIR:-target}/release/riskplan
fi
[ -x "$RP" ] || { echo "reproduce.sh: $RP is not an executable riskplan binary" >&2; exit 2; }

rm -rf "$OUT" "$FIG"
mkdir -p "$OUT"/{plans,trajectories} "$FIG"
RAW=$(mktemp -d)   # one report per risk / verify query, collected into risk.jsonl and verify.jsonl
trap 'rm -rf "$RAW"' EXIT
mkdir -p "$RAW"/{risk,verify}
LOG=$OUT/log.txt
: >"$LOG"
T_START=$(date +%s)
STAGES=()
stage_begin() { STAGE=$1; T_STAGE=$(date +%s); echo "== $STAGE" | tee -a "$LOG" >&2; }
stage_end() { STAGES+=("$STAGE=$(($(date +%s) - T_STAGE))"); }

# Runs riskplan, appending its stderr to the log; exit status 0, or 1 where allowed ("no plan",
# "not certified"), passes; anything else stops the script.
run() {
  local allow1=$1; shift
  echo "+ riskplan $*" >>"$LOG"
  local rc=0 t0 t1
  t0=$(date +%s.%N)
  "$RP" "$@" 2>>"$LOG" </dev/null || rc=$?
  t1=$(date +%s.%N)
  awk -v a="$t0" -v b="$t1" -v rc="$rc" 'BEGIN { printf "  [exit %d, %.2f s]\n", rc, b - a }' >>"$LOG"
  if [ "$rc" -ne 0 ] && ! { [ "$allow1" = allow1 ] && [ "$rc" -eq 1 ]; }; then
    echo "reproduce.sh: riskplan $* failed with exit status $rc (see $LOG)" >&2
    tail -n 5 "$LOG" >&2
    exit 1
  fi
}

stage_begin prepare
"${PY[@]}" prepare --scenes "$S" --out "$OUT" --spot-mc "$SPOT_MC" --traj-mc "$TRAJ_MC" --traj-times "$TRAJ_TIMES"
stage_end

stage_begin contours
run strict contour --scene "$S/illustrative-1.json" --delta 0.2 0.1 0.07 0.05 --mc "$CONTOUR_MC" \
  --window -0.7 0.7 -0.7 0.7 --out "$FIG/illustrative-1-contours.svg"
run strict contour --scene "$S/illustrative-2.json" --time 0 0.5 1 --mc "$CONTOUR_MC" \
  --out "$FIG/illustrative-2-contours.svg"
run strict contour --scene "$S/example-a1-2d.json" --mc "$CONTOUR_MC" --out "$FIG/example-a1-2d-contours.svg"
for x3 in minus0.5:-0.5 0:0 plus0.5:0.5; do
  run strict contour --scene "$S/example-a2-3d.json" --slice "x3=${x3#*:}" --mc "$CONTOUR_MC" \
    --out "$FIG/example-a2-3d-slice-x3-${x3%%:*}.svg"
done
stage_end

stage_begin risk
# tasks: id, scene, time, delta, Monte Carlo samples, coordinates (space-separated)
while IFS=$'\t' read -r id scene t delta mc coords; do
  read -ra X <<<"$coords"
  run strict risk --scene "$S/$scene.json" --bound cantelli --point "${X[@]}" --time "$t" --delta "$delta" --mc "$mc" \
    >"$RAW/risk/$id.json"
done <"$OUT/risk-tasks.tsv"
stage_end

stage_begin verify-given
# tasks: id, scene, trajectory file, delta
while IFS=$'\t' read -r id scene traj delta; do
  run allow1 verify --scene "$S/$scene.json" --bound cantelli --trajectory "$traj" --method both --delta "$delta" \
    >"$RAW/verify/$id.json"
done <"$OUT/verify-tasks.tsv"
stage_end

stage_begin bench
run strict bench --suite paper --bound cantelli --scenes "$S" --seeds "$SEEDS" --time-limit "$TIME_LIMIT" \
  --audit-samples "$AUDIT_SAMPLES" --audit-times "$AUDIT_TIMES" --out "$OUT/bench.jsonl" >"$OUT/bench-table.md"
stage_end

stage_begin plans
# tasks: scene, planner, improve (0/1), file stem
"${PY[@]}" plans --bench "$OUT/bench.jsonl" >"$OUT/plan-tasks.tsv"
while IFS=$'\t' read -r scene planner improve stem; do
  extra=()
  [ "$improve" = 1 ] && extra=(--improve)
  run allow1 plan --scene "$S/$scene.json" --bound cantelli --planner "$planner" "${extra[@]}" --seed 1 --time-limit "$TIME_LIMIT" \
    --out "$OUT/plans/$stem.json" --figure "$FIG/$stem.svg"
  if [ -f "$OUT/plans/$stem.json" ]; then
    run allow1 verify --scene "$S/$scene.json" --bound cantelli --trajectory "$OUT/plans/$stem.json" --method both \
      >"$RAW/verify/plan--$stem.json"
  fi
done <"$OUT/plan-tasks.tsv"
stage_end

"${PY[@]}" collect --raw "$RAW" --out "$OUT"

T_END=$(date +%s)
# the run's facts, for the report's header
RP_BIN=$RP RP_SEEDS=$SEEDS RP_TIME_LIMIT=$TIME_LIMIT RP_AUDIT_SAMPLES=$AUDIT_SAMPLES RP_AUDIT_TIMES=$AUDIT_TIMES \
RP_SPOT_MC=$SPOT_MC RP_TRAJ_MC=$TRAJ_MC RP_TRAJ_TIMES=$TRAJ_TIMES RP_CONTOUR_MC=$CONTOUR_MC \
RP_ARGS="$*" RP_KNOBS="SEEDS=$SEEDS TIME_LIMIT=$TIME_LIMIT${KNOBS_SET[*]:+ ${KNOBS_SET[*]}}" RP_START=$T_START RP_END=$T_END RP_STAGES="${STAGES[*]}" \
RP_NPROC=$(nproc) RP_CPU=$(grep -m1 '^model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ *//' || true) \
RP_GIT=$(git rev-parse --short HEAD 2>/dev/null || echo unknown) \
RP_DIRTY=$(GIT_OPTIONAL_LOCKS=0 git status --porcelain --untracked-files=no 2>/dev/null | wc -l) \
RP_VERSION=$("$RP" --version 2>/dev/null || echo unknown) \
  "${PY[@]}" meta --out "$OUT/run.json"

stage_begin report
"${PY[@]}" report --scenes "$S" --results "$OUT" --figures "$FIG" --out docs/reproduction.md
stage_end
echo "wrote docs/reproduction.md ($(($(date +%s) - T_START)) s)" >&2
