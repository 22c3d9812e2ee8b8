#!/usr/bin/env bash
# Issue 8's interrupted-walk check on the simulator, by hand (minutes, not a ctest):
#   scripts/bench-kill-resume.sh [KEYFRAMES] [KILL_AFTER_S] [OUT_DIR]
# Maps KEYFRAMES (default 600) of the hand-held walk at 1 Hz once uninterrupted, once killed with
# SIGKILL after KILL_AFTER_S seconds (default: random 5-20) and resumed from the first frame not
# committed; then prints, for both models, keyframes, segments and the whole-model ATE against
# the walk's ground truth.
# Environment: SIGHTMAP (the binary, default build/sightmap).
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${SIGHTMAP:-build/sightmap}
frames=${1:-600}
kill_after=${2:-$((5 + RANDOM % 16))}
out=${3:-out/kill-resume}
[ -x "$bin" ] || { echo "error: $bin not found: build first (scripts/build.sh) or set SIGHTMAP" >&2; exit 1; }
source="sim:office?fps=1&frames=$frames"
mkdir -p "$out"
rm -f "$out"/whole.db* "$out"/killed.db*

if [ ! -f "$out/gt/groundtruth.txt" ] || [ "$(grep -vc '^#' "$out/gt/groundtruth.txt")" != "$frames" ]; then
  echo "== ground truth: rendering the walk's $frames keyframes" >&2
  rm -rf "$out/gt"
  "$bin" sim generate --scene office --trajectory handheld --session 1 --seed 7 --frames "$frames" \
    --fps 1 --queries 0 --out "$out/gt" >/dev/null
fi

echo "== uninterrupted" >&2
"$bin" map --source "$source" --model "$out/whole.db" --headless >"$out/whole.log" 2>&1

echo "== killed after $kill_after s" >&2
"$bin" map --source "$source" --model "$out/killed.db" --headless >"$out/killed-1.log" 2>&1 &
pid=$!
sleep "$kill_after"
kill -9 "$pid" 2>/dev/null || { echo "error: the run ended before the kill; pass a shorter KILL_AFTER_S" >&2; exit 1; }
wait "$pid" 2>/dev/null || true
committed=$("$bin" info "$out/killed.db" --json | sed -n 's/.*"keyframes": *\([0-9]*\).*/\1/p' | head -1)
echo "== resumed from frame $committed ($committed keyframes committed before the kill)" >&2
"$bin" map --source "$source" --model "$out/killed.db" --headless --start-frame "$committed" \
  >"$out/killed-2.log" 2>&1

for model in whole killed; do
  "$bin" export "$out/$model.db" --trajectory "$out/$model-trajectory.txt" >/dev/null
  keyframes=$("$bin" info "$out/$model.db" --json | sed -n 's/.*"keyframes": *\([0-9]*\).*/\1/p' | head -1)
  segments=$("$bin" info "$out/$model.db" --json | sed -n 's/.*"segments": *\([0-9]*\).*/\1/p' | head -1)
  ate=$("$bin" eval trajectory --gt "$out/gt/groundtruth.txt" --est "$out/$model-trajectory.txt" |
    awk '/^ATE rmse/ {print $3}')
  printf '%-8s keyframes %5s  segments %4s  ATE %s m\n' "$model" "$keyframes" "$segments" "$ate"
done
