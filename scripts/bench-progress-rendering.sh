#!/usr/bin/env bash
# Mapping throughput with and without the off-screen progress image (issue 7's target: within
# 10%). Runs `sightmap map` on the simulator headless, alternating with and without
# --progress-png so machine noise hits both alike, and prints keyframes/s per run, the medians and
# their ratio.
#   scripts/bench-progress-rendering.sh [RUNS] [FRAMES]     (default 3 runs of 300 keyframes: the default walk;
#   shorter runs overweigh the final render, which happens once at the end)
set -euo pipefail

runs=${1:-3}
frames=${2:-300}
root=$(cd "$(dirname "$0")/.." && pwd)
binary=${SIGHTMAP_BINARY:-$root/build/sightmap}
[[ -x "$binary" ]] || { echo "error: $binary not found: run scripts/build.sh first" >&2; exit 1; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

rate() {  # keyframes/s of one run; $1 = with|without
  local extra=()
  [[ $1 == with ]] && extra=(--progress-png "$work/progress.png")
  rm -f "$work"/model.db*
  "$binary" map --source "sim:office?fps=1&frames=$frames" --model "$work/model.db" --headless \
    "${extra[@]}" --json 2>/dev/null |
    python3 -c 'import json, sys; print(json.load(sys.stdin)["keyframes_per_s"])'
}

median() { sort -g | awk '{v[NR] = $1} END {print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2}'; }

with=()
without=()
for ((i = 1; i <= runs; i++)); do
  with+=("$(rate with)")
  without+=("$(rate without)")
  printf 'run %d: %.1f keyframes/s with the progress image, %.1f without\n' "$i" \
    "${with[-1]}" "${without[-1]}"
done
m_with=$(printf '%s\n' "${with[@]}" | median)
m_without=$(printf '%s\n' "${without[@]}" | median)
awk -v a="$m_with" -v b="$m_without" 'BEGIN {
  printf "median: %.1f keyframes/s with, %.1f without: %.1f%% slower (target <= 10%%)\n", a, b,
         100 * (1 - a / b) }'
