#!/usr/bin/env bash
# Configures and builds sightmap into build/ (the binary lands at build/sightmap).
set -euo pipefail
cd "$(dirname "$0")/.."
cmake -S . -B build -DCMAKE_BUILD_TYPE=RelWithDebInfo "$@"
cmake --build build -j"$(nproc)"
