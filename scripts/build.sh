#!/usr/bin/env bash
# Configures and builds sightmap into build/ (the binary lands at build/sightmap).
set -euo pipefail
cd "$(dirname "$0")/.."
# Ninja for a new build folder (it compiles a target's files without waiting for the libraries the
# target links); a folder configured before keeps its generator, which cannot change in place.
generator=()
[[ -f build/CMakeCache.txt ]] || generator=(-G Ninja)
cmake -S . -B build "${generator[@]}" -DCMAKE_BUILD_TYPE=RelWithDebInfo "$@"
cmake --build build -j"$(nproc)"
