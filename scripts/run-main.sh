#!/usr/bin/env bash
# The main job on a fresh Debian 12 machine: install what is missing, build, and map the
# simulator's default walk (300 s hand-held at 10 Hz, every frame tracked, keyframes at 1 Hz and
# where the overlap runs out) headless into a fresh model in out/, with its PLY, progress image
# and trajectory, then print the summary (about 90 s here).
# A SOURCE given as the first argument is mapped instead (openni://, FILE.oni, tum:DIR, ...).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
scripts/build.sh
source_arg=${1:-sim:office?fps=10}
mkdir -p out
# A fresh model: `map` on an existing one would resume it as a second session.
rm -f out/office.db out/office.db-wal out/office.db-shm
build/sightmap map --source "$source_arg" --model out/office.db --ply out/office.ply \
  --progress-png out/office.png --trajectory-out out/office-trajectory.txt --headless
