#!/usr/bin/env bash
# Configures and builds sightmap into build/ (the binary lands at build/sightmap).
set -euo pipefail
cd "$(dirname "$0")/.."
# Ninja for a new build folder: it starts a target's files before the libraries they link are
# built, which keeps both cores busy; a folder configured before keeps its generator.
generator=()
[[ -f build/CMakeCache.txt ]] || generator=(-G Ninja)
cmake -S . -B build "${generator[@]}" -DCMAKE_BUILD_TYPE=RelWithDebInfo "$@"
cmake --build build -j"$(nproc)"
