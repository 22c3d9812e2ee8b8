#!/usr/bin/env bash
# The interrupted-walk check on the simulator, by hand (minutes, not a ctest):
#   scripts/bench-kill-resume.sh [SECONDS] [KILL_AFTER_S] [OUT_DIR] [FPS] [SEED]
# Maps SECONDS (default 600) of the hand-held walk at FPS (default 10, every frame tracked,
# keyframes at 1 Hz) once uninterrupted, once killed with SIGKILL after KILL_AFTER_S seconds
# (default: random 30-150) and resumed with the same command (which continues after the last
# stored frame); then
# prints, for both models, keyframes, parts and the whole-model ATE against the walk's ground
# truth (rendered once with `sim generate`, which at 10 Hz takes minutes of its own).
# Environment: SIGHTMAP (the binary, default build/sightmap).
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${SIGHTMAP:-build/sightmap}
seconds=${1:-600}
kill_after=${2:-$((30 + RANDOM % 121))}
out=${3:-out/kill-resume}
fps=${4:-10}
seed=${5:-11}
[ -x "$bin" ] || { echo "error: $bin not found: build first (scripts/build.sh) or set SIGHTMAP" >&2; exit 1; }
frames=$(awk -v s="$seconds" -v f="$fps" 'BEGIN { printf "%d", s * f }')
source="sim:office?fps=$fps&frames=$frames&seed=$seed"
mkdir -p "$out"
rm -f "$out"/whole.db* "$out"/killed.db*

gt="$out/gt-$fps-$frames-$seed"
if [ ! -f "$gt/groundtruth.txt" ]; then
  echo "== ground truth: rendering the walk's $frames frames" >&2
  rm -rf "$gt"
  "$bin" sim generate --scene office --trajectory handheld --session 1 --seed "$seed" \
    --frames "$frames" --fps "$fps" --queries 0 --out "$gt" >/dev/null
fi

echo "== uninterrupted" >&2
"$bin" map --source "$source" --model "$out/whole.db" --headless >"$out/whole.log" 2>&1

echo "== killed after $kill_after s" >&2
"$bin" map --source "$source" --model "$out/killed.db" --headless >"$out/killed-1.log" 2>&1 &
pid=$!
sleep "$kill_after"
kill -9 "$pid" 2>/dev/null || { echo "error: the run ended before the kill; pass a shorter KILL_AFTER_S" >&2; exit 1; }
wait "$pid" 2>/dev/null || true
echo "== resumed with the same command ($("$bin" info "$out/killed.db" --json |
  sed -n 's/^  "keyframes": *\([0-9]*\).*/\1/p') keyframes committed)" >&2
# The same command continues the walk after its last stored frame (map says so on stderr).
"$bin" map --source "$source" --model "$out/killed.db" --headless >"$out/killed-2.log" 2>&1
grep -m1 '^continuing' "$out/killed-2.log" >&2 || true

for model in whole killed; do
  "$bin" export "$out/$model.db" --trajectory "$out/$model-trajectory.txt" >/dev/null
  info=$("$bin" info "$out/$model.db" --json)
  keyframes=$(sed -n 's/^  "keyframes": *\([0-9]*\).*/\1/p' <<<"$info")
  parts=$(sed -n 's/^  "segments": *\([0-9]*\).*/\1/p' <<<"$info")
  ate=$("$bin" eval trajectory --gt "$gt/groundtruth.txt" --est "$out/$model-trajectory.txt" |
    awk '$1 == "ATE" && $2 == "rmse" {print $3; exit}')
  printf '%-8s keyframes %5s  parts %4s  ATE %s m\n' "$model" "$keyframes" "$parts" "$ate"
done
