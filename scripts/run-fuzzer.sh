#!/usr/bin/env bash
# run-fuzzer.sh FUZZER SECONDS CORPUS SEEDS FINDINGS [libFuzzer flags...]: one harness for SECONDS
# on CORPUS (kept and grown between runs) and SEEDS (fuzz_seeds_test's). An input that crashes,
# trips a sanitizer, times out or runs out of memory is saved as FINDINGS/<name>-<kind>-<hash>,
# and the run fails. What ctest's fuzz_* tests and scripts/fuzz.sh call.
set -euo pipefail
fuzzer=$1 seconds=$2 corpus=$3 seeds=$4 findings=$5
shift 5
if [[ ! -d "$seeds" ]]; then
  echo "error: no seed corpus at $seeds: run the ordinary build's tests first" \
    "(fuzz_seeds_test writes it)" >&2
  exit 1
fi
mkdir -p "$corpus" "$findings"
name=$(basename "$fuzzer" _fuzzer)
log="$findings/$name.log"
status=0
"$fuzzer" -max_total_time="$seconds" -timeout=25 -rss_limit_mb=2560 -print_final_stats=1 \
  -artifact_prefix="$findings/$name-" "$@" "$corpus" "$seeds" >"$log" 2>&1 || status=$?
# The whole log when something was found (scripts/fuzz.sh prints every run's figures).
if [[ $status -ne 0 ]]; then
  cat "$log"
  echo "error: $name found a problem (exit $status); the input is in $findings/$name-*" >&2
fi
exit $status
