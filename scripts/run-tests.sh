#!/usr/bin/env bash
# Installs what is missing, builds, and runs every test (unit, real recordings, CLI end to end).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
scripts/build.sh
cd build
ctest --output-on-failure --timeout 600 -j"$(nproc)"
cd ..
# A short run of every fuzzer (clang, ASan and UBSan; seeds written by the tests above).
scripts/fuzz.sh 10
