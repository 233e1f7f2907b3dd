#!/usr/bin/env bash
# The reliability jobs (docs/reliability.md), after scripts/test.sh has built the project and
# run the tests (whose workflow session, build/workflow_local/local, is the uninterrupted
# reference; REFERENCE names another finished session, e.g. build/e2e_tiny):
#   1. kill-and-rerun: KILLS (default 1) random SIGKILLs per stage on a copy of REFERENCE;
#   2. every unit test and the end-to-end workflow session under ASan + UBSan (clang,
#      build-sanitize/, scripts/test_sanitizers.sh);
#   3. every fuzz target for FUZZ_SECONDS (default 30) (clang, build-fuzz/).
# Prints the wall time of each step. Environment: REFERENCE, KILLS, KILL_SEED (default: the
# commit's hash, printed, so a failure can be replayed), FUZZ_SECONDS.
set -euo pipefail
cd "$(dirname "$0")/.."
kills="${KILLS:-1}"
seed="${KILL_SEED:-$(( 16#$(git rev-parse --short=6 HEAD 2>/dev/null || echo 1) % 32768 ))}"
fuzz_seconds="${FUZZ_SECONDS:-30}"
scratch="$(mktemp -d)"
trap 'rm -rf "$scratch"' EXIT
step() {
  local name="$1"; shift
  local start=$SECONDS
  echo "== $name"
  "$@"
  echo "== $name: $((SECONDS - start)) s"
}
reference="${REFERENCE:-build/workflow_local/local}"
test -f "$reference/reports/metrics.json" \
  || { echo "no finished session in $reference: run scripts/test.sh first"; exit 1; }
echo "kill seed $seed ($kills kill(s) per stage)"
step "kill and rerun" env FOURD_BIN=build/bin bash tests/e2e/kill_rerun.sh "$reference" \
  "$scratch/kill" "$kills" "$seed"
step "sanitizers: unit tests" bash scripts/test_sanitizers.sh --unit
step "sanitizers: end to end" bash scripts/test_sanitizers.sh --e2e
step "fuzzing" bash tests/fuzz/run_fuzz.sh "$fuzz_seconds"
