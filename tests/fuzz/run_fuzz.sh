#!/usr/bin/env bash
# Builds the libFuzzer targets (CMake preset "fuzz": clang, ASan + UBSan, in build-fuzz/) and
# runs each for a bounded time on its seed corpus. Fails on a crash, a sanitizer report, a leak,
# a timeout (one input taking more than 10 s), running out of memory (2 GB), or an exception
# other than the typed errors of pipeline/core/error.h. A failing input is saved as
# build-fuzz/artifacts/<target>/crash-* (or leak-, timeout-, oom-): reproduce it with
#   build-fuzz/bin/fuzz_<target> build-fuzz/artifacts/<target>/crash-...
# and, once fixed, commit it under tests/fuzz/regressions/<target>/ (fourd_tests then checks
# that it is refused with a typed error).
#
# usage: run_fuzz.sh [SECONDS_PER_TARGET (default 60)] [TARGET...]   (default: every target)
# FUZZ_JOBS: targets run at once (default: one per core).
# Prints, per target, the executions and their rate; new inputs the fuzzer finds are kept in
# build-fuzz/corpus/<target>/ (not in the repository).
set -euo pipefail
cd "$(dirname "$0")/../.."
seconds="${1:-60}"
shift || true
source scripts/ccache_env.sh
cmake --preset fuzz > build-fuzz.cmake.log 2>&1 || { cat build-fuzz.cmake.log; exit 1; }
ninja -C build-fuzz -j"$(nproc)" fourd_fuzz_targets
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
  for d in tests/fuzz/corpus/*/; do targets+=("$(basename "$d")"); done
fi
# One target: its run, then its summary line (and, on failure, the report) in its log.
fuzz_one() {
  local t="$1" exe="build-fuzz/bin/fuzz_$1" corpus="build-fuzz/corpus/$1"
  local artifacts="build-fuzz/artifacts/$1/" log="build-fuzz/fuzz_$1.log" code
  # Seeds: the repository's corpus and its older-format files (read only: libFuzzer writes the
  # inputs it finds into the first folder only).
  local seeds=("tests/fuzz/corpus/$1")
  [ -d "tests/fuzz/legacy/$1" ] && seeds+=("tests/fuzz/legacy/$1")
  mkdir -p "$corpus" "$artifacts"
  set +e
  ASAN_OPTIONS=detect_leaks=1:allocator_may_return_null=1 \
  UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
    "$exe" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -malloc_limit_mb=2048 \
      -print_final_stats=1 -close_fd_mask=1 -artifact_prefix="$artifacts" \
      "$corpus" "${seeds[@]}" > "$log" 2>&1
  code=$?
  set -e
  echo "$code" > "build-fuzz/fuzz_$t.exit"
}
for t in "${targets[@]}"; do
  [ -x "build-fuzz/bin/fuzz_$t" ] || { echo "no fuzz target $t"; exit 2; }
done
# The targets run side by side, one per core (each is single-threaded).
jobs_max="${FUZZ_JOBS:-$(nproc)}"
echo "== fuzzing ${#targets[@]} target(s), ${seconds} s each, ${jobs_max} at a time"
failed=()
summary=""
start=$SECONDS
for t in "${targets[@]}"; do
  while [ "$(jobs -pr | wc -l)" -ge "$jobs_max" ]; do wait -n || true; done
  rm -f "build-fuzz/fuzz_$t.exit"
  fuzz_one "$t" &
done
wait
for t in "${targets[@]}"; do
  log="build-fuzz/fuzz_$t.log"
  code=$(cat "build-fuzz/fuzz_$t.exit" 2>/dev/null || echo 99)
  runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -1)
  cov=$(grep -oE 'cov: [0-9]+' "$log" | tail -1 | sed 's/cov: //')
  line=$(printf '%-16s %10s execs %8s /s  cov %6s  exit %d' "$t" "${runs:-?}" "${rate:-?}" \
         "${cov:-?}" "$code")
  summary+="$line"$'\n'
  if [ "$code" -ne 0 ]; then
    failed+=("$t")
    echo "== fuzz_$t failed (exit $code):"
    grep -m1 -B2 -A30 -E "ERROR: (AddressSanitizer|LeakSanitizer|libFuzzer)|runtime error|terminate called|deadly signal" "$log" || tail -40 "$log"
  fi
done
echo "== fuzzing summary ($((SECONDS - start)) s)"
printf '%s' "$summary"
if [ ${#failed[@]} -gt 0 ]; then
  echo "fuzzing FAILED: ${failed[*]} (inputs in build-fuzz/artifacts/)"
  exit 1
fi
echo "fuzzing ok: no crash, leak, timeout or untyped exception"
