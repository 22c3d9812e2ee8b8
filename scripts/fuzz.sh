#!/usr/bin/env bash
# fuzz.sh [SECONDS]: builds the libFuzzer harnesses (fuzz/) with clang, AddressSanitizer and
# UndefinedBehaviorSanitizer into build-fuzz/, and runs each for SECONDS (default 10: the test
# command's short run; a long run is e.g. `scripts/fuzz.sh 1800`). Needs the seed corpora that
# the ordinary build's tests write (build/fuzz-seeds). Findings land in build-fuzz/findings/.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-10}
# -O1, as libFuzzer's documentation builds: the sanitized build took 315 s instead of 388 s at -O2
# on 2 cores. Inputs run in 10 s went either way (label_request 69k -> 40k, locate_request
# 167 -> 267, photo 618 -> 711); for a long hunt, -O2 may find more an hour.
generator=()
[[ -f build-fuzz/CMakeCache.txt ]] || generator=(-G Ninja)
cmake -S . -B build-fuzz "${generator[@]}" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_C_COMPILER=clang-14 \
  -DCMAKE_CXX_COMPILER=clang++-14 -DSIGHTMAP_FUZZ=ON -DSIGHTMAP_BUILD_TESTS=OFF \
  "-DCMAKE_C_FLAGS_RELWITHDEBINFO=-O1 -g -DNDEBUG" "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g -DNDEBUG" \
  -DSIGHTMAP_FUZZ_SECONDS="$seconds" -DSIGHTMAP_FUZZ_SEEDS="$PWD/build/fuzz-seeds" >/dev/null
cmake --build build-fuzz --target fuzzers -j"$(nproc)"
cd build-fuzz
rm -f findings/*.log
ctest --output-on-failure -L fuzz -j"$(nproc)" --timeout $((seconds * 2 + 600)) || status=$?
echo "fuzzing, ${seconds} s each:"
for log in findings/*.log; do
  awk -v name="$(basename "$log" .log)" '
    /^stat::number_of_executed_units/ { runs = $NF }
    /^stat::average_exec_per_sec/ { rate = $NF }
    /^stat::new_units_added/ { added = $NF }
    END { printf "  %-20s %10s inputs %6s/s %5s new\n", name, runs, rate, added }' "$log"
done
exit "${status:-0}"
